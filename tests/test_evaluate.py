import gymnasium as gym
import numpy as np
import pytest
import torch
from torchrl.envs import TransformedEnv

from spn_torchrl.envs import make_batched_env, make_population_env, task_spec
from spn_torchrl.errors import ConfigError, EvaluatorError
from spn_torchrl.evaluation.processes import ProcessEvaluator
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.seeds import episode_seed
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
    env.reset(seed=seed)  # what set_seed does, then the evaluator's reset
    obs, _ = env.reset()
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
    evaluator = PopulationEvaluator(make_population_env(env_id, size), spn, spec.max_episode_steps)
    try:
        result = evaluator(genomes, seed=123)
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
    evaluator = PopulationEvaluator(make_population_env("CartPole-v1", 8), spn, spec.max_episode_steps)
    try:
        full = evaluator(genomes, seed=5)
        part = evaluator(genomes[:3], seed=5)
        again = evaluator(genomes, seed=5)
    finally:
        evaluator.close()
    assert len(set(full.steps.tolist())) > 1  # episodes of different lengths, each counted to its own end
    assert torch.equal(part.returns, full.returns[:3]) and torch.equal(part.steps, full.steps[:3])
    assert torch.equal(again.returns, full.returns)
    with pytest.raises(ValueError, match="holds 8 individuals"):
        PopulationEvaluator(make_population_env("CartPole-v1", 8), spn, 10)(torch.zeros(9, spn.genome_size), 0)


def test_episode_seeds_differ_per_generation_and_phase():
    seeds = {episode_seed(0, g, p) for g in range(50) for p in (0, 1)}
    assert len(seeds) == 100 and all(0 <= s < 2**31 for s in seeds)
    assert episode_seed(1, 3, 0) == episode_seed(1, 3, 0)


def test_two_worker_processes_give_the_same_episodes_for_the_first_workers_slots():
    spec, spn, genomes, _ = setup("CartPole-v1", 8, 1.0)
    one = PopulationEvaluator(make_population_env("CartPole-v1", 8), spn, spec.max_episode_steps)
    two = PopulationEvaluator(make_population_env("CartPole-v1", 8, num_workers=2), spn, spec.max_episode_steps)
    try:
        a, b = one(genomes, seed=11), two(genomes, seed=11)
        part = two(genomes[:6], seed=11)
    finally:
        one.close()
        two.close()
    # worker 0 is seeded like the single process; ParallelEnv derives worker 1's seed on its own
    assert torch.equal(a.returns[:4], b.returns[:4]) and torch.equal(a.steps[:4], b.steps[:4])
    assert part.returns.shape == (6,) and torch.equal(part.returns, b.returns[:6])


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
            a, b = one(genomes[:count], seed=9), many(genomes[:count], seed=9)
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


def test_a_worker_process_that_cannot_build_its_env_raises_its_error():
    spec, spn, _, _ = setup("CartPole-v1", 4, 1.0)
    with pytest.raises(ConfigError, match="env.num_workers must be 1"):
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
            a, b = direct(genomes[:count], seed=3), through_torchrl(genomes[:count], seed=3)
            assert (
                torch.equal(a.returns, b.returns) and torch.equal(a.steps, b.steps) and torch.equal(a.spikes, b.spikes)
            )
        if backend == "cartpole_batch":
            assert len(set(a.steps.tolist())) > 1  # episodes ended at different steps: the masks were used
    finally:
        direct.close()
        through_torchrl.close()


def test_a_worker_process_killed_is_a_clear_error():
    spec, spn, genomes, _ = setup("CartPole-v1", 6, 1.0)
    evaluator = ProcessEvaluator(spn, "CartPole-v1", 6, "cartpole_batch", 1, spec.max_episode_steps, 2)
    try:
        evaluator._processes[1].kill()
        with pytest.raises(EvaluatorError, match=r"evaluator process 1 \(slots 3..5\) died \(exit code -9\)"):
            evaluator(genomes, seed=0)
    finally:
        evaluator.close()
