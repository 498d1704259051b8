import os
import signal
import time

import gymnasium as gym
import numpy as np
import pytest
import torch
from torchrl.envs import TransformedEnv

from spn_torchrl.envs import make_batched_env, make_transformed_env, task_spec
from spn_torchrl.errors import ConfigError, EvaluatorError
from spn_torchrl.evaluation.processes import CLOSE_GRACE_S, ProcessEvaluator
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.seeds import FITNESS, REEVALUATION, episode_seed, episode_seeds
from spn_torchrl.snn.policies import PopulationSPN, build_spn, init_fixed_weights
from spn_torchrl.training import ga


def setup(env_id, size, sigma):
    spec = task_spec(env_id)
    generator = torch.Generator().manual_seed(0)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, 64, generator)
    kwargs = dict(discrete=spec.discrete, action_low=spec.action_low, action_high=spec.action_high)
    spn = PopulationSPN(w1, w2, **kwargs)
    genomes = ga.initial_population(size, spn.genome_size, sigma, generator)
    return spec, spn, genomes, kwargs


def plain_gymnasium_episode(env_id, spn_kwargs, w1, w2, genome, seed):
    """The reference: one gymnasium env, one single-policy call per step."""
    policy = build_spn(w1, w2, genome, **spn_kwargs)
    env = gym.make(env_id)
    obs, _ = env.reset(seed=seed)
    total, steps, spikes, done = 0.0, 0, 0.0, False
    while not done:
        action, s = policy(torch.as_tensor(obs, dtype=torch.float32)[None])
        a = int(action[0]) if spn_kwargs["discrete"] else action[0].numpy().astype(np.float64)
        obs, reward, terminated, truncated, _ = env.step(a)
        total, steps, spikes, done = total + reward, steps + 1, spikes + float(s[0]), terminated or truncated
    env.close()
    return total, steps, spikes


@pytest.mark.parametrize("env_id,size,sigma", [("CartPole-v1", 6, 1.0), ("Swimmer-v5", 2, 1.0)])
def test_rollout_equals_plain_gymnasium(env_id, size, sigma):
    spec, spn, genomes, kwargs = setup(env_id, size, sigma)
    evaluator = PopulationEvaluator(make_transformed_env(env_id, size), spn, spec.max_episode_steps)
    try:
        result = evaluator(genomes, 123)
    finally:
        evaluator.close()
    for i in range(size):
        ret, steps, spikes = plain_gymnasium_episode(env_id, kwargs, spn.w1, spn.w2, genomes[i], 123 + i)
        assert result.steps[i] == steps
        assert result.returns[i].item() == pytest.approx(ret, rel=1e-4, abs=1e-3)
        assert result.spikes[i].item() == spikes
    assert result.total_steps == int(result.steps.sum())


def test_members_run_to_their_own_end_and_fewer_genomes_fill_leading_slots():
    spec, spn, genomes, _ = setup("CartPole-v1", 8, 1.0)
    evaluator = PopulationEvaluator(make_transformed_env("CartPole-v1", 8), spn, spec.max_episode_steps)
    try:
        full = evaluator(genomes, 5)
        part = evaluator(genomes[:3], 5)
        again = evaluator(genomes, 5)
    finally:
        evaluator.close()
    assert len(set(full.steps.tolist())) > 1  # episodes of different lengths, each counted to its own end
    assert torch.equal(part.returns, full.returns[:3]) and torch.equal(part.steps, full.steps[:3])
    assert torch.equal(again.returns, full.returns)
    with pytest.raises(ValueError, match="holds 8 individuals"):
        PopulationEvaluator(make_transformed_env("CartPole-v1", 8), spn, 10)(torch.zeros(9, spn.genome_size), 0)


def test_episode_seeds_differ_per_generation_and_role_and_count_up_by_index():
    seeds = {episode_seed(0, g, role) for g in range(50) for role in (FITNESS, REEVALUATION)}
    assert len(seeds) == 100 and all(0 <= s < 2**31 for s in seeds)
    assert episode_seed(1, 3, 0) == episode_seed(1, 3, 0)
    assert np.array_equal(episode_seeds(1, 3, REEVALUATION, 4), episode_seed(1, 3, REEVALUATION) + np.arange(4))


@pytest.mark.parametrize(
    "env_id,backend", [("CartPole-v1", "gymnasium"), ("CartPole-v1", "cartpole_batch"), ("Swimmer-v5", "mujoco_batch")]
)
def test_an_episode_depends_on_its_seed_not_on_its_slot(env_id, backend):
    spec, spn, genomes, _ = setup(env_id, 6, 1.0)
    steps = 40 if backend == "mujoco_batch" else spec.max_episode_steps
    evaluator = PopulationEvaluator(make_batched_env(env_id, 6, backend=backend), spn, steps)
    seeds, order = np.array([3, 9, 27, 81, 243, 729]), np.array([5, 2, 0, 4, 1, 3])
    try:
        a = evaluator(genomes, seeds)
        b = evaluator(genomes[order], seeds[order])
        c = evaluator(genomes[order[:2]], seeds[order[:2]])
    finally:
        evaluator.close()
    for field in ("returns", "steps", "spikes"):
        assert torch.equal(getattr(b, field), getattr(a, field)[order])
        assert torch.equal(getattr(c, field), getattr(a, field)[order[:2]])


@pytest.mark.slow  # processes or a CLI in a subprocess
@pytest.mark.parametrize(
    "env_id,backend,processes", [("CartPole-v1", "cartpole_batch", 3), ("Swimmer-v5", "mujoco_batch", 2)]
)
def test_worker_processes_give_the_one_process_episodes(env_id, backend, processes):
    spec, spn, genomes, _ = setup(env_id, 7, 1.0)
    steps = 40 if backend == "mujoco_batch" else spec.max_episode_steps
    one = PopulationEvaluator(make_batched_env(env_id, 7, backend=backend), spn, steps)
    many = ProcessEvaluator(spn, env_id, 7, backend, 1, steps, processes)
    try:
        assert [p.is_alive() for p in many._processes] == [True] * processes
        for count in (7, 5, 2):  # a full set, a partial one, fewer genomes than processes
            a, b = one(genomes[:count], 9), many(genomes[:count], 9)
            assert (
                torch.equal(a.returns, b.returns) and torch.equal(a.steps, b.steps) and torch.equal(a.spikes, b.spikes)
            )
        with pytest.raises(ValueError, match="hold 7 individuals"):
            many(torch.zeros(8, spn.genome_size), 0)
        assert len(many.gather("peak_memory_mb")) == processes
    finally:
        one.close()
        workers = many._processes
        many.close()
    assert not any(p.is_alive() for p in workers)


@pytest.mark.slow  # processes or a CLI in a subprocess
def test_a_worker_process_that_cannot_build_its_env_raises_its_error():
    spec, spn, _, _ = setup("CartPole-v1", 4, 1.0)
    with pytest.raises(ConfigError, match="env.threads must be 1"):
        ProcessEvaluator(spn, "CartPole-v1", 4, "cartpole_batch", 2, spec.max_episode_steps, 2)


@pytest.mark.parametrize(
    "env_id,backend,steps", [("CartPole-v1", "cartpole_batch", 500), ("Swimmer-v5", "mujoco_batch", 30)]
)
def test_batch_backends_stepped_directly_give_torchrls_step_episodes(env_id, backend, steps):
    spec, spn, genomes, _ = setup(env_id, 6, 1.0)
    direct = PopulationEvaluator(make_batched_env(env_id, 6, backend=backend), spn, steps)
    # the same env behind an empty transform is stepped through TorchRL's step_and_maybe_reset
    through_torchrl = PopulationEvaluator(TransformedEnv(make_batched_env(env_id, 6, backend=backend)), spn, steps)
    assert direct.direct and not through_torchrl.direct
    try:
        for count in (6, 4):
            a, b = direct(genomes[:count], 3), through_torchrl(genomes[:count], 3)
            assert (
                torch.equal(a.returns, b.returns) and torch.equal(a.steps, b.steps) and torch.equal(a.spikes, b.spikes)
            )
        if backend == "cartpole_batch":
            assert len(set(a.steps.tolist())) > 1  # episodes ended at different steps: the masks were used
    finally:
        direct.close()
        through_torchrl.close()


@pytest.mark.slow  # processes or a CLI in a subprocess
def test_a_worker_process_killed_is_a_clear_error():
    spec, spn, genomes, _ = setup("CartPole-v1", 6, 1.0)
    evaluator = ProcessEvaluator(spn, "CartPole-v1", 6, "cartpole_batch", 1, spec.max_episode_steps, 2)
    try:
        evaluator._processes[1].kill()
        with pytest.raises(EvaluatorError, match=r"evaluator process 1 \(slots 3..5\) died \(exit code -9\)"):
            evaluator(genomes, 0)
    finally:
        evaluator.close()


@pytest.mark.slow  # processes or a CLI in a subprocess
@pytest.mark.parametrize("request_size", ["small", "larger than its pipe"])
def test_a_stopped_worker_process_is_a_clear_error_within_the_call_timeout(request_size):
    spec, spn, genomes, _ = setup("CartPole-v1", 6, 1.0)
    if request_size != "small":  # 1.5 MB of weight genomes: the stopped worker's pipe fills, the send blocks
        spn = PopulationSPN(spn.w1, spn.w2, genome_kind="weights", discrete=True)
        genomes = torch.zeros(2000, spn.genome_size)
    with pytest.raises(ConfigError, match="evaluator.call_timeout_s must be > 0 or null, got 0"):
        ProcessEvaluator(spn, "CartPole-v1", 6, "cartpole_batch", 1, 500, 2, call_timeout_s=0)
    evaluator = ProcessEvaluator(
        spn, "CartPole-v1", len(genomes), "cartpole_batch", 1, spec.max_episode_steps, 2, call_timeout_s=2.0
    )
    workers = list(evaluator._processes)
    stop, pid = evaluator.bounds[1][1] - 1, workers[1].pid
    try:
        os.kill(pid, signal.SIGSTOP)
        began = time.monotonic()
        with pytest.raises(EvaluatorError) as raised:
            evaluator(genomes, 0)
        # bounds with room for a loaded host: the error comes at the timeout, close() kills after its grace
        timeout = evaluator.call_timeout_s
        assert timeout <= time.monotonic() - began < timeout + 3.0
        assert str(raised.value) == (
            f"evaluator process 1 (slots {evaluator.bounds[1][0]}..{stop}, pid {pid}) did not evaluate within "
            "evaluator.call_timeout_s=2 s: it is stopped (SIGSTOP?)"
        )
        began = time.monotonic()
        evaluator.close()
        assert time.monotonic() - began < CLOSE_GRACE_S + 3.0  # a loaded host's idle worker may exit that late
        assert not any(p.is_alive() for p in workers) and workers[1].exitcode == -signal.SIGKILL
    finally:
        evaluator.close()
        for process in workers:  # a failed assertion must not leave a stopped process behind
            if process.is_alive():
                process.kill()
