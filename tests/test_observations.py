"""normalize_observations: brax's running statistics, the per-slot moments the evaluators gather, and the
normalisation the SPN applies (fast unit tests; the runs are in test_observations_run.py)."""

from __future__ import annotations

import numpy as np
import torch

from spn_torchrl.config import SNNConfig
from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.evaluation import machine_evaluator
from spn_torchrl.evaluation.rollout import ObservedMoments, PopulationEvaluator
from spn_torchrl.lifecycle import config_changes
from spn_torchrl.snn import observations as obs
from spn_torchrl.snn.policies import init_fixed_weights, spn_from_config


def brax_update(state: dict, batch: np.ndarray) -> dict:
    """brax running_statistics.update, written as brax writes it (on the batch itself), in float64."""
    count = state["count"] + batch.shape[0]
    diff_old = batch - state["mean"]
    mean = state["mean"] + diff_old.sum(0) / count
    summed = state["summed_variance"] + (diff_old * (batch - mean)).sum(0)
    std = np.clip(np.sqrt(np.maximum(summed, 0) / count), 1e-6, 1e6)
    return {"count": count, "mean": mean, "summed_variance": summed, "std": std}


def test_the_statistics_start_as_braxs_and_normalise_nothing():
    stats = obs.initial_stats(3)
    assert stats["count"] == 0 and not stats["mean"].any() and (stats["std"] == 1).all()
    x = torch.randn(5, 3)
    assert torch.equal(obs.normalize(x, obs.policy_norm(stats)), x)  # (x - 0) * 1, exactly
    assert obs.normalize(x, None) is x
    assert obs.update(stats, obs.moments(torch.empty(0, 3))) is stats  # an empty batch changes nothing


def test_batched_updates_are_braxs_and_give_the_mean_and_std_of_everything_seen():
    rng = np.random.default_rng(0)
    batches = [rng.normal(loc, scale, size=(size, 4)) for loc, scale, size in ((3, 2, 50), (-1, 0.5, 7), (10, 4, 300))]
    ours = obs.initial_stats(4)
    theirs = {k: v.numpy() if isinstance(v, torch.Tensor) else v for k, v in obs.initial_stats(4).items()}
    for batch in batches:
        ours = obs.update(ours, obs.moments(torch.from_numpy(batch)))
        theirs = brax_update(theirs, batch)
    every = np.concatenate(batches)
    assert ours["count"] == theirs["count"] == len(every)
    for key in ("mean", "summed_variance", "std"):
        np.testing.assert_allclose(ours[key].numpy(), theirs[key], rtol=1e-10)
    np.testing.assert_allclose(ours["mean"].numpy(), every.mean(0), rtol=1e-12)
    np.testing.assert_allclose(ours["std"].numpy(), every.std(0), rtol=1e-10)


def test_std_is_clipped_as_braxs():
    stats = obs.update(obs.initial_stats(2), obs.moments(torch.tensor([[1.0, 0.0], [1.0, 4e6], [1.0, -4e6]])))
    assert stats["std"][0] == 1e-6 and stats["std"][1] == 1e6
    mean, inv_std = obs.policy_norm(stats)
    assert mean.dtype == inv_std.dtype == torch.float32 and inv_std[0] == np.float32(1e6)


def test_slot_moments_are_the_batchs_whatever_the_shards():
    x = torch.randn(6, 9, 3, dtype=torch.float64)  # 6 slots, 9 steps
    active = torch.rand(6, 9) < 0.7
    seen = ObservedMoments(6)
    for step in range(9):
        seen.add(x[:, step].float(), active[:, step])
    count, total, squares = obs.slot_moments(seen.count, seen.sum, seen.squares)
    kept = x.float().double()[active]
    assert count == int(active.sum())
    torch.testing.assert_close(total, kept.sum(0), rtol=1e-12, atol=1e-12)
    torch.testing.assert_close(squares, (kept * kept).sum(0), rtol=1e-12, atol=1e-12)
    # shards of the slots, concatenated in slot order, give the same bits
    parts = [ObservedMoments(n) for n in (2, 4)]
    for step in range(9):
        parts[0].add(x[:2, step].float(), active[:2, step])
        parts[1].add(x[2:, step].float(), active[2:, step])
    joined = [torch.cat([getattr(p, k) for p in parts]) for k in ("count", "sum", "squares")]
    again = obs.slot_moments(*joined)
    assert again[0] == count and torch.equal(again[1], total) and torch.equal(again[2], squares)


def spn_for(env_id: str, hidden: int = 16):
    spec = task_spec(env_id)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, hidden, torch.Generator().manual_seed(0))
    return spec, spn_from_config(SNNConfig(hidden=hidden), "connections", spec, w1, w2)


def test_the_spn_acts_on_the_normalised_observations():
    spec, spn = spn_for("HalfCheetah-v5")
    genomes = torch.randn(4, spn.genome_size)
    x = torch.randn(4, spec.n_obs) * 5
    norm = (torch.randn(4, spec.n_obs), torch.rand(4, spec.n_obs) + 0.5)
    spn.set_genomes(genomes)
    raw, _ = spn(x)
    spn.set_observation_norm(norm)
    normalised, _ = spn(x)
    spn.set_observation_norm(None)
    assert torch.equal(spn(x)[0], raw)
    assert torch.equal(spn((x - norm[0]) * norm[1])[0], normalised) and not torch.equal(normalised, raw)


def test_the_evaluator_gathers_what_each_policy_saw_and_processes_gather_the_same():
    spec, spn = spn_for("CartPole-v1")
    genomes, seeds = torch.randn(6, spn.genome_size), np.arange(6) + 11
    norm = (torch.randn(6, spec.n_obs) * 0.1, torch.rand(6, spec.n_obs) + 0.5)
    env = make_batched_env(spec.env_id, 6, backend="cartpole_batch")
    one = PopulationEvaluator(env, spn, spec.max_episode_steps)
    try:
        raw, normalised = one(genomes, seeds), one(genomes, seeds, norm)
    finally:
        one.close()
    assert raw.obs_count is None and not torch.equal(raw.returns, normalised.returns)
    assert torch.equal(normalised.obs_count, normalised.steps)  # one observation seen per step taken
    two = machine_evaluator(spn, spec.env_id, 6, "cartpole_batch", 1, spec.max_episode_steps, processes=2)
    try:
        sharded = two(genomes, seeds, norm)
    finally:
        two.close()
    for key in ("returns", "steps", "spikes", "obs_count", "obs_sum", "obs_squares"):
        assert torch.equal(getattr(sharded, key), getattr(normalised, key)), key


def test_a_saved_config_from_before_the_option_resumes_under_it():
    saved = {"seed": 0, "algo": {"generations": 2}}
    assert config_changes(saved, {**saved, "normalize_observations": False}, "ga") == ([], [])
    refused, _ = config_changes(saved, {**saved, "normalize_observations": True}, "ga")
    assert refused == ["normalize_observations False -> True"]


def test_the_ppo_normaliser_applies_what_it_was_set_to():
    size = 3
    layer = obs.ObservationNormalizer(size)
    x = torch.randn(2, size)
    assert torch.equal(layer(x), x)
    norm = (torch.randn(size), torch.rand(size) + 0.1)
    layer.set(norm)
    assert torch.equal(layer(x), (x - norm[0]) * norm[1])
    assert set(layer.state_dict()) == {"mean", "inv_std"}
