import math

import pytest
import torch
from tensordict.nn import TensorDictModule

from spn_torchrl.config import SNNConfig
from spn_torchrl.snn.neurons import spn_dynamics
from spn_torchrl.snn.policies import PopulationSPN, build_spn, init_fixed_weights


def make(kind="connections", n=5, m=3, h=64, seed=0, **kw):
    w1, w2 = init_fixed_weights(n, m, h, torch.Generator().manual_seed(seed))
    return PopulationSPN(w1, w2, genome_kind=kind, **kw)


def test_fixed_weights_are_kaiming_normal_and_seeded():
    w1, w2 = init_fixed_weights(200, 50, 400, torch.Generator().manual_seed(1))
    assert w1.shape == (400, 200) and w2.shape == (50, 400)
    assert abs(w1.std().item() - math.sqrt(2 / 200)) < 0.05 * math.sqrt(2 / 200)
    assert abs(w2.std().item() - math.sqrt(2 / 400)) < 0.05 * math.sqrt(2 / 400)
    again, _ = init_fixed_weights(200, 50, 400, torch.Generator().manual_seed(1))
    assert torch.equal(w1, again)


def test_mask_threshold_on_sigmoid_of_score():
    spn = make(n=1, m=1, h=1)
    genomes = torch.tensor([[0.0, -1e-4], [1e-4, -3.0]])
    x1, x2 = spn.masks(genomes)
    assert x1.flatten().tolist() == [True, True] and x2.flatten().tolist() == [False, False]
    spn_hi = make(n=1, m=1, h=1, snn=SNNConfig(score_threshold=0.7))
    x1, _ = spn_hi.masks(torch.tensor([[math.log(0.7 / 0.3) + 1e-4, 0.0], [0.8, 0.0]]))
    assert x1.flatten().tolist() == [True, False]


def test_effective_weights_are_masked_fixed_weights_and_genome_layout():
    spn = make(n=4, m=2, h=3)
    genome = torch.randn(1, spn.genome_size)
    w1, w2 = spn.effective_weights(genome)
    layer1 = genome[0, :12].reshape(3, 4) >= 0
    layer2 = genome[0, 12:].reshape(2, 3) >= 0
    assert torch.equal(w1[0], spn.w1 * layer1) and torch.equal(w2[0], spn.w2 * layer2)
    weights = make("weights", n=4, m=2, h=3)
    v1, v2 = weights.effective_weights(genome)
    assert torch.equal(v1[0], genome[0, :12].reshape(3, 4)) and torch.equal(v2[0], genome[0, 12:].reshape(2, 3))


@pytest.mark.parametrize("kind", ["connections", "weights"])
def test_batched_forward_equals_single_forwards(kind):
    spn = make(kind, n=17, m=6, action_low=-torch.ones(6), action_high=torch.ones(6))
    genomes = torch.randn(8, spn.genome_size) * (0.3 if kind == "weights" else 1.0)
    obs = torch.randn(8, 17) * 3
    spn.set_genomes(genomes)
    actions, spikes = spn(obs)
    for i in range(8):
        single = build_spn(
            spn.w1, spn.w2, genomes[i], genome_kind=kind, action_low=-torch.ones(6), action_high=torch.ones(6)
        )
        a, s = single(obs[i : i + 1])
        assert torch.allclose(actions[i], a[0], atol=1e-6) and spikes[i] == s[0]


def test_continuous_actions_are_clipped_max_potentials():
    spn = make(n=5, m=3, action_low=torch.tensor([-0.1, -1.0, -1.0]), action_high=torch.tensor([0.1, 1.0, 1.0]))
    genomes = torch.randn(4, spn.genome_size)
    obs = torch.randn(4, 5) * 5
    spn.set_genomes(genomes)
    actions, _ = spn(obs)
    raw, _ = spn_dynamics(spn.w1_eff, spn.w2_eff, obs)
    assert torch.equal(actions, torch.clamp(raw, spn.action_low, spn.action_high))
    assert (actions[:, 0].abs() <= 0.1).all()


def test_discrete_actions_are_argmax_indices():
    spn = make(n=4, m=2, discrete=True)
    genomes = torch.randn(6, spn.genome_size)
    obs = torch.randn(6, 4)
    spn.set_genomes(genomes)
    actions, _ = spn(obs)
    raw, _ = spn_dynamics(spn.w1_eff, spn.w2_eff, obs)
    assert actions.dtype == torch.long and torch.equal(actions, raw.argmax(-1))


def test_tensordict_module_writes_action_and_spikes():
    from tensordict import TensorDict

    spn = make(n=4, m=2, discrete=True)
    spn.set_genomes(torch.randn(3, spn.genome_size))
    module = TensorDictModule(spn, in_keys=["observation"], out_keys=["action", "hidden_spikes"])
    td = module(TensorDict({"observation": torch.randn(3, 4)}, batch_size=[3]))
    assert td["action"].shape == (3,) and td["hidden_spikes"].shape == (3,)


def test_errors_are_clear():
    spn = make(n=4, m=2)
    with pytest.raises(RuntimeError, match="set_genomes"):
        spn(torch.randn(2, 4))
    with pytest.raises(ValueError, match=r"genomes must be \[P, "):
        spn.set_genomes(torch.randn(2, 7))
    with pytest.raises(ValueError, match="genome_kind"):
        make("synapses")


@pytest.mark.parametrize("kind", ["connections", "weights"])
def test_each_genome_uses_its_runs_fixed_weights_bit_for_bit(kind):
    """Lockstep: an SPN of three runs' fixed weights gives each genome exactly what its run's own SPN gives it."""
    singles = [make(kind, n=17, m=6, seed=seed) for seed in (0, 1, 2)]
    stacked = PopulationSPN(
        torch.stack([s.w1 for s in singles]), torch.stack([s.w2 for s in singles]), genome_kind=kind
    )
    assert stacked.runs == 3 and stacked.genome_size == singles[0].genome_size
    genomes = torch.randn(12, stacked.genome_size) * (0.3 if kind == "weights" else 1.0)
    runs = torch.tensor([2, 0, 1, 1, 0, 2, 2, 2, 0, 1, 0, 1])
    obs = torch.randn(12, 17) * 3
    stacked.set_genomes(genomes, runs)
    actions, spikes = stacked(obs)
    for r, single in enumerate(singles):
        mine = runs == r
        single.set_genomes(genomes[mine])
        a, s = single(obs[mine])
        assert torch.equal(actions[mine], a) and torch.equal(spikes[mine], s)
    with pytest.raises(ValueError, match="runs must be given exactly when"):
        stacked.set_genomes(genomes)
    with pytest.raises(ValueError, match="runs must be given exactly when"):
        singles[0].set_genomes(genomes, runs)
    with pytest.raises(ValueError, match=r"runs must be \[12\]"):
        stacked.set_genomes(genomes, runs[:5])
