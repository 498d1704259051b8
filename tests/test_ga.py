import torch

from spn_torchrl.training import ga


def gen(seed=0):
    return torch.Generator().manual_seed(seed)


def test_generation_zero_is_mirrored_pairs_around_zero():
    pop = ga.initial_population(10, 7, 0.01, gen())
    assert pop.shape == (10, 7)
    assert torch.allclose(pop[0::2] + pop[1::2], torch.zeros(5, 7))
    assert not torch.allclose(pop[0::2], pop[2::2][:1].expand(5, 7))
    x0, x1 = pop[0] >= 0, pop[1] >= 0  # complementary masks (no exact zeros)
    assert torch.equal(x0, ~x1)


def test_generation_zero_around_a_center():
    center = torch.arange(6.0)
    pop = ga.initial_population(4, 6, 0.1, gen(), center)
    assert torch.allclose((pop[0::2] + pop[1::2]) / 2, center.expand(2, 6))


def test_truncation_keeps_the_top_and_children_are_mirrored():
    pop = torch.randn(20, 5)
    fitness = torch.randn(20)
    children = ga.next_generation(pop, fitness, sigma=0.01, truncation=0.25, generator=gen())
    assert children.shape == pop.shape
    top = set(torch.argsort(fitness, descending=True)[:5].tolist())
    midpoints = (children[0::2] + children[1::2]) / 2
    for mid in midpoints:
        parent = int(torch.cdist(mid[None], pop).argmin())
        assert parent in top and torch.allclose(mid, pop[parent], atol=1e-6)
    half = (children[0::2] - children[1::2]) / 2
    assert 0.005 < half.std().item() < 0.02


def test_same_seed_same_result_and_different_seed_differs():
    pop, fitness = torch.randn(12, 4), torch.randn(12)
    a = ga.next_generation(pop, fitness, sigma=0.1, truncation=0.5, generator=gen(3))
    b = ga.next_generation(pop, fitness, sigma=0.1, truncation=0.5, generator=gen(3))
    c = ga.next_generation(pop, fitness, sigma=0.1, truncation=0.5, generator=gen(4))
    assert torch.equal(a, b) and not torch.equal(a, c)


def test_parents_drawn_with_replacement():
    pop, fitness = torch.randn(40, 3), torch.arange(40.0)
    children = ga.next_generation(pop, fitness, sigma=1e-6, truncation=0.05, generator=gen())  # 2 parents
    mids = (children[0::2] + children[1::2]) / 2
    parents = {int(torch.cdist(m[None], pop).argmin()) for m in mids}
    assert parents <= {38, 39}


def test_elitism_option_keeps_the_best_unchanged():
    pop, fitness = torch.randn(10, 3), torch.randn(10)
    children = ga.next_generation(pop, fitness, sigma=0.1, truncation=0.2, generator=gen(), elitism=2)
    best = torch.argsort(fitness, descending=True)[:2]
    assert torch.equal(children[-2:], pop[best])


def test_num_parents():
    assert ga.num_parents(200, 0.25) == 50
    assert ga.num_parents(4, 0.1) == 1


def test_elite_candidates_and_pick_elite():
    fitness = torch.tensor([1.0, 5.0, 3.0, 5.0, 0.0])
    cands = ga.elite_candidates(fitness, 3)
    assert cands.tolist() == [1, 3, 2]  # ties keep population order
    returns = torch.tensor([[1.0, 1.0], [4.0, 2.0], [2.0, 2.0]])
    assert ga.pick_elite(cands, returns) == (3, 3.0)
