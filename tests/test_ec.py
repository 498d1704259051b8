"""EC's update (training/ec.py) against hand-computed values, and its config's defaults (EC's method at the paper's
budget)."""

from __future__ import annotations

import math

import pytest
import torch

from spn_torchrl.config import ECConfig
from spn_torchrl.evaluation.shards import decode_genomes, encode_genomes
from spn_torchrl.snn.policies import PopulationSPN, SNNConfig
from spn_torchrl.training import ec


def test_the_defaults_are_ecs_update_at_the_papers_budget(make_config):
    algo = make_config("algo=conn_ec").algo
    assert isinstance(algo, ECConfig) and algo.kind == "ec" and algo.name == "conn_ec"
    assert (algo.population, algo.generations, algo.elite_episodes) == (200, 100, 10)
    assert (algo.lr, algo.eps, algo.p_init) == (0.15, 1e-3, 0.5)
    assert (algo.adam_b1, algo.adam_b2, algo.adam_eps) == (0.9, 0.999, 1e-8)
    assert algo.evaluation_slots == 210 and algo.elite_candidates == 1 and algo.genome == "connections"


def test_centered_rank_is_rank_over_n_minus_one_minus_a_half():
    # ranks of [3, 1, 2, 5] are [2, 0, 1, 3]; / 3 - 0.5
    got = ec.centered_rank(torch.tensor([3.0, 1.0, 2.0, 5.0]))
    assert torch.allclose(got, torch.tensor([1 / 6, -0.5, -1 / 6, 0.5]))


def test_centered_rank_ranks_ties_in_population_order():
    # [1, 1, 0]: the 0 is lowest, then the first 1, then the second: ranks [1, 2, 0]; / 2 - 0.5
    assert ec.centered_rank(torch.tensor([1.0, 1.0, 0.0])).tolist() == [0.0, 0.5, -0.5]


def test_nes_gradient_is_the_weighted_mean_of_mask_minus_p():
    p = torch.tensor([0.5, 0.2])
    masks = torch.tensor([[True, False], [False, True]])
    # 0.5 * ([1, 0] - p) = [0.25, -0.1];  -0.5 * ([0, 1] - p) = [0.25, -0.4];  mean: [0.25, -0.25]
    got = ec.nes_gradient(p, masks, torch.tensor([0.5, -0.5]))
    assert torch.allclose(got, torch.tensor([0.25, -0.25]))


def test_adams_two_first_steps_by_hand():
    state = ec.adam_state(1)
    first, state = ec.adam_step(torch.tensor([0.1]), state, 0.9, 0.999, 1e-8)
    # m = 0.01, v = 1e-5; m_hat = 0.1, v_hat = 0.01: 0.1 / (0.1 + 1e-8)
    assert first.item() == pytest.approx(0.1 / (0.1 + 1e-8), rel=1e-6) and state["t"] == 1
    second, state = ec.adam_step(torch.tensor([-0.2]), state, 0.9, 0.999, 1e-8)
    # m = 0.9 * 0.01 - 0.1 * 0.2 = -0.011, v = 0.999e-5 + 0.001 * 0.04 = 4.999e-5
    # m_hat = -0.011 / 0.19 = -0.0578947, v_hat = 4.999e-5 / 0.001999 = 0.0250075, sqrt 0.1581376
    assert state["m"].item() == pytest.approx(-0.011, rel=1e-6)
    assert state["v"].item() == pytest.approx(4.999e-5, rel=1e-5)
    assert second.item() == pytest.approx(-0.0578947 / 0.1581376, rel=1e-5) and state["t"] == 2


def test_one_update_moves_p_by_lr_along_the_gradients_sign_and_clips():
    algo = ECConfig(lr=0.15, eps=1e-3)
    p = torch.tensor([0.5, 0.5, 0.95, 0.05])
    masks = torch.tensor([[True, False, True, False], [False, True, False, True]])
    fitness = torch.tensor([10.0, 0.0])  # the first mask is better: weights [0.5, -0.5]
    new_p, adam = ec.update(p, ec.adam_state(4), masks, fitness, algo)
    # gradient [0.25, -0.25, 0.25, -0.25]; Adam's first direction is its sign: p +- 0.15, then the clip
    assert torch.allclose(new_p, torch.tensor([0.65, 0.35, 0.999, 0.001]), atol=1e-6)
    assert adam["t"] == 1


def test_a_generation_of_equal_fitness_still_steps_on_the_rank_of_ties():
    # ties keep population order, so the later mask ranks higher: EC's argsort does the same
    algo = ECConfig()
    p = torch.full((1,), 0.5)
    masks = torch.tensor([[False], [True]])
    new_p, _ = ec.update(p, ec.adam_state(1), masks, torch.tensor([1.0, 1.0]), algo)
    assert new_p.item() == pytest.approx(0.65, abs=1e-6)


def test_masks_are_uniform_below_p_and_the_deterministic_mask_is_p_above_a_half():
    p = torch.tensor([0.0, 1.0, 0.3, 0.5, 0.5000001])
    masks = ec.sample_masks(p, 20_000, torch.Generator().manual_seed(0))
    assert masks[:, 0].sum() == 0 and masks[:, 1].all()
    assert masks[:, 2].float().mean().item() == pytest.approx(0.3, abs=0.02)
    assert ec.deterministic_mask(p).tolist() == [False, True, False, False, True]


def test_sampling_is_the_generators():
    p = torch.full((50,), 0.5)
    one = ec.sample_masks(p, 4, torch.Generator().manual_seed(3))
    assert torch.equal(one, ec.sample_masks(p, 4, torch.Generator().manual_seed(3)))
    assert not torch.equal(one, ec.sample_masks(p, 4, torch.Generator().manual_seed(4)))


@pytest.mark.parametrize("threshold", [0.01, 0.5, 0.99])
def test_mask_genomes_give_the_spn_and_the_workers_the_mask_itself(threshold):
    w1, w2 = torch.randn(4, 3), torch.randn(2, 4)
    spn = PopulationSPN(w1, w2, snn=SNNConfig(score_threshold=threshold))
    masks = ec.sample_masks(torch.full((20,), 0.5), 6, torch.Generator().manual_seed(1))
    genomes = ec.mask_genomes(masks)
    x1, x2 = spn.masks(genomes)
    assert torch.equal(torch.cat([x1.flatten(1), x2.flatten(1)], 1), masks)
    assert torch.equal(ec.genome_masks(genomes), masks)
    assert torch.equal(decode_genomes(encode_genomes(spn, genomes), "connections", 20), genomes)


def test_the_step_keeps_p_for_the_elite_and_updates_it_after():
    algo = ECConfig(population=4)
    state = ec.initial_state(algo, 6, torch.Generator().manual_seed(0))
    assert torch.equal(state["p"], torch.full((6,), 0.5)) and state["population"].shape == (4, 6)
    assert set(state["population"].unique().tolist()) <= {math.inf, -math.inf}
    step = ec.ECStep(algo, state)
    pool, candidates = step.elite_pool(state["population"], torch.arange(4.0))
    assert candidates.tolist() == [0] and (pool == -math.inf).all()  # p = 0.5 everywhere: no synapse is > 0.5
    generator = torch.Generator().manual_seed(1)
    population = step.advance(state["population"], torch.arange(4.0), generator)
    assert population.shape == (4, 6) and not torch.equal(step.p, state["p"])
    saved = step.state()
    assert torch.equal(saved["p"], step.p) and saved["adam"]["t"] == 1


def test_analysis_counts_an_ec_runs_budget_in_generations(tmp_path):
    from omegaconf import OmegaConf

    from spn_torchrl.analysis.runs import RunRecord

    config = OmegaConf.create({"algo": {"name": "conn_ec", "kind": "ec", "generations": 3}})
    run = RunRecord(tmp_path, config, [{"generation": 1}, {"generation": 2}])
    assert (run.budget, run.done, run.finished, run.progress_text) == (3, 2, False, "2 of 3 generations")
