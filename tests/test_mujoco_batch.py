"""The mujoco_batch backend against Gymnasium v5: same resets, observations, rewards and episode returns."""

from __future__ import annotations

from collections.abc import Iterator

import gymnasium as gym
import numpy as np
import pytest
import torch
from tensordict import TensorDict

from spn_torchrl.envs import make_transformed_env, task_spec
from spn_torchrl.envs.mujoco import MujocoBatchEnv
from spn_torchrl.errors import ConfigError
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import PopulationSPN, init_fixed_weights

TASKS = ["HalfCheetah-v5", "Swimmer-v5", "HumanoidStandup-v5"]
TOL = 1e-6


def gym_envs(env_id: str, count: int, seed: int) -> tuple[list[gym.Env], np.ndarray]:
    """Gymnasium envs seeded as GymWrapper.set_seed + reset seeds a vector env: reset(seed+i), then reset()."""
    envs = [gym.make(env_id) for _ in range(count)]
    obs = []
    for i, env in enumerate(envs):
        env.reset(seed=seed + i)
        obs.append(env.reset()[0])
    return envs, np.stack(obs)


@pytest.mark.parametrize("env_id", TASKS)
def test_steps_match_gymnasium(env_id: str) -> None:
    count, seed = 3, 11
    env = MujocoBatchEnv(env_id, count)
    env.set_seed(seed)
    td = env.reset()
    envs, obs = gym_envs(env_id, count, seed)
    np.testing.assert_allclose(env._obs, obs, rtol=0, atol=TOL)
    np.testing.assert_array_equal(td["observation"].numpy(), obs.astype(np.float32))
    rng = np.random.default_rng(0)
    low, high = envs[0].action_space.low, envs[0].action_space.high
    impact_seen = False
    for _ in range(200):
        action = rng.uniform(low, high, size=(count, len(low))).astype(np.float32)
        td["action"] = torch.from_numpy(action)
        nxt = env.step(td)["next"]
        for i, genv in enumerate(envs):
            o, r, terminated, truncated, info = genv.step(action[i])
            np.testing.assert_allclose(env._obs[i], o, rtol=0, atol=TOL)
            assert abs(env._reward[i] - r) <= TOL
            assert nxt["reward"][i, 0].item() == np.float32(r)
            assert not nxt["done"][i, 0] and not terminated and not truncated
            impact_seen |= info.get("reward_impact", 0.0) < 0
        td = nxt.clone()
    if env_id == "HumanoidStandup-v5":  # contact forces enter both the observation and the reward
        assert impact_seen
        assert np.abs(env.sims.cfrc_ext[:, 1:]).max() > 0


@pytest.mark.parametrize("env_id", ["HalfCheetah-v5", "HumanoidStandup-v5", "Hopper-v5", "Ant-v5"])
def test_partial_reset_and_step_follow_gymnasium(env_id: str) -> None:
    count, seed = 3, 5
    env = MujocoBatchEnv(env_id, count)
    env.set_seed(seed)
    env.reset()
    envs, _ = gym_envs(env_id, count, seed)
    before = env._obs.copy()
    # reset sub-env 1 only: it draws its next reset state, as Gymnasium's env 1 does
    td = env.reset(TensorDict({"_reset": torch.tensor([[False], [True], [False]])}, batch_size=[count]))
    np.testing.assert_allclose(env._obs[1], envs[1].reset()[0], rtol=0, atol=TOL)
    np.testing.assert_array_equal(env._obs[[0, 2]], before[[0, 2]])
    # step sims 0 and 1 only: sim 2 must not move
    action = np.full((count, env.model.nu), 0.3, dtype=np.float32)
    td["action"] = torch.from_numpy(action)
    td["_step"] = torch.tensor([True, True, False])
    nxt = env.step(td)["next"]
    for i in (0, 1):
        o, r, *_ = envs[i].step(action[i])
        np.testing.assert_allclose(env._obs[i], o, rtol=0, atol=TOL)
        assert abs(env._reward[i] - r) <= TOL
    np.testing.assert_array_equal(env._obs[2], before[2])
    assert nxt["reward"][2, 0] == 0 and env._elapsed.tolist() == [1, 1, 0]


def test_time_limit_truncates_at_1000_steps() -> None:
    env = make_transformed_env("Swimmer-v5", 2, backend="mujoco_batch")
    env.set_seed(0)
    td = env.reset()
    for step in range(1, 1001):
        td["action"] = torch.zeros(2, 2)
        nxt = env.step(td)["next"]
        assert bool(nxt["truncated"].all()) == (step == 1000)
        assert bool(nxt["done"].all()) == (step == 1000) and not nxt["terminated"].any()
        td = nxt.exclude("reward", "done", "terminated", "truncated")
    assert nxt["step_count"].flatten().tolist() == [1000, 1000]


def spn_results_on_both_backends(env_id: str, steps: int):
    """3 seeded SPN genomes on 4 slots (an idle slot) through PopulationEvaluator: (gymnasium, mujoco_batch)."""
    torch.set_num_threads(1)
    spec = task_spec(env_id)
    gen = torch.Generator().manual_seed(1)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, 64, gen)
    spn = PopulationSPN(w1, w2, action_low=spec.action_low, action_high=spec.action_high)
    genomes = torch.randn(3, spn.genome_size, generator=gen)
    results = {}
    for backend in ("gymnasium", "mujoco_batch"):
        evaluator = PopulationEvaluator(make_transformed_env(env_id, 4, backend=backend), spn, steps)
        results[backend] = evaluator(genomes, 123)
        evaluator.close()
    return results["gymnasium"], results["mujoco_batch"]


@pytest.mark.parametrize(
    "env_id,steps",
    [("HalfCheetah-v5", 150), ("Swimmer-v5", 150), ("HumanoidStandup-v5", 40), ("Reacher-v5", 50), ("Pusher-v5", 100)],
)
def test_spn_returns_match_gymnasium_backend(env_id: str, steps: int) -> None:
    """A population of SPNs, 3 genomes on 4 slots (an idle slot), through PopulationEvaluator on both backends."""
    ref, got = spn_results_on_both_backends(env_id, steps)
    assert torch.equal(got.steps, ref.steps) and got.total_steps == 3 * steps
    torch.testing.assert_close(got.returns, ref.returns, rtol=1e-6, atol=1e-6)
    assert torch.equal(got.spikes, ref.spikes)
    assert ref.returns.std() > 0  # the genomes behave differently: the comparison has teeth


def test_unknown_id_is_a_config_error() -> None:
    with pytest.raises(
        ConfigError, match="mujoco_batch steps HalfCheetah-v5, Swimmer-v5, HumanoidStandup-v5, Hopper-v5"
    ):
        make_transformed_env("Hopper-v4", 2, backend="mujoco_batch")


def test_humanoidstandup_threads_step_the_same_simulations() -> None:
    """HumanoidStandup's one-MjData-per-simulation path: 3 threads taking simulations as they come give every
    observation and reward of 1 thread bit for bit, with a partial step mask, and time the physics alone."""
    count, seed = 7, 3
    envs = [MujocoBatchEnv("HumanoidStandup-v5", count, num_threads=threads) for threads in (1, 3)]
    rng = np.random.default_rng(2)
    for env in envs:
        env.set_seed(seed)
        env.reset()
    mask = np.array([True, True, False, True, True, True, False])
    for step in range(30):
        action = rng.uniform(-0.4, 0.4, size=(count, 17)).astype(np.float32)
        ids = None if step % 3 else np.flatnonzero(mask)
        outs = [env.step_slots(action if ids is None else action[ids], ids) for env in envs]
        for a, b in zip(*outs, strict=True):
            assert torch.equal(a, b)
    assert np.abs(envs[1].sims.cfrc_ext[:, 1:]).max() > 0
    for env in envs:
        assert 0 < env.physics_seconds
        env.close()


TERMINATING = [  # the tasks of envs/mujoco_tasks.py, each ending its episodes early
    "Hopper-v5",
    "Walker2d-v5",
    "Ant-v5",
    "Humanoid-v5",
    "InvertedPendulum-v5",
    "InvertedDoublePendulum-v5",
]


def paired_envs(env_id: str, count: int, seed: int) -> tuple[MujocoBatchEnv, list[gym.Env]]:
    """``count`` slots of a task seeded with ``seed`` and Gymnasium's envs seeded alike: their first observations
    are equal bit for bit."""
    env = MujocoBatchEnv(env_id, count)
    env.set_seed(seed)
    env.reset()
    envs, obs = gym_envs(env_id, count, seed)
    np.testing.assert_array_equal(env._obs, obs)
    return env, envs


def random_actions(genv: gym.Env, count: int, steps: int) -> Iterator[np.ndarray]:
    """``steps`` float32 actions [count, nu], uniform over the task's action space."""
    rng = np.random.default_rng(0)
    low, high = genv.action_space.low, genv.action_space.high
    for _ in range(steps):
        yield rng.uniform(low, high, size=(count, len(low))).astype(np.float32)


def reward_terms(info: dict) -> tuple[set[str], set[str]]:
    """The reward terms a Gymnasium step's info reports, and those of them that are nonzero."""
    reported = {k for k in info if k.startswith("reward_") or k.endswith("_penalty")}
    return reported, {k for k in reported if info[k] != 0}


@pytest.mark.parametrize("env_id", TERMINATING)
def test_terminating_tasks_match_gymnasium_through_terminations(env_id: str) -> None:
    """Random actions on 3 slots for 300 steps, each slot reset (its own generator) when Gymnasium's env
    terminates: every reset and step observation and reward equal Gymnasium's bit for bit, and so does the
    healthy-state termination. Every reward term Gymnasium reports takes part (is nonzero on some step): the
    healthy reward drops on the terminal steps, and Ant's and Humanoid's contact forces are nonzero in the
    observation and the contact cost."""
    count = 3
    env, envs = paired_envs(env_id, count, seed=3)
    terminations, terms, active = 0, set(), set()
    for action in random_actions(envs[0], count, 300):
        _, reward, terminated, truncated = env.step_slots(action)
        for i, genv in enumerate(envs):
            o, r, gym_terminated, _, info = genv.step(action[i])
            np.testing.assert_array_equal(env._obs[i], o)
            assert env._reward[i] == r and reward[i].item() == np.float32(r)
            assert bool(terminated[i]) == gym_terminated and not truncated[i]
            assert (info["reward_survive"] == 0) == gym_terminated  # the healthy reward goes with the healthy state
            reported, nonzero = reward_terms(info)
            terms, active = terms | reported, active | nonzero
            if gym_terminated:
                terminations += 1
                env.reset(TensorDict({"_reset": torch.arange(count)[:, None] == i}, batch_size=[count]))
                np.testing.assert_array_equal(env._obs[i], genv.reset()[0])
    assert terminations >= 10 and "reward_survive" in terms and active == terms
    if env_id in ("Ant-v5", "Humanoid-v5"):
        assert "reward_contact" in terms and np.abs(env.sims.cfrc_ext[:, 1:]).max() > 0
    env.close()


def test_inverted_double_pendulum_cart_force_matches_gymnasium() -> None:
    """The cart pushed full force each way for 30 steps, past its falls: it hits the rail's ends, so the constraint
    force in the observation is nonzero, and every observation, reward and termination equals Gymnasium's."""
    env, envs = paired_envs("InvertedDoublePendulum-v5", 2, seed=4)
    action = np.array([[1.0], [-1.0]], dtype=np.float32)
    force_seen = False
    for _ in range(30):
        _, _, terminated, _ = env.step_slots(action)
        for i, genv in enumerate(envs):
            o, r, gym_terminated, _, _ = genv.step(action[i])
            np.testing.assert_array_equal(env._obs[i], o)
            assert env._reward[i] == r and bool(terminated[i]) == gym_terminated
        force_seen |= bool((env._obs[:, 8] != 0).any())
    assert force_seen
    env.close()


@pytest.mark.parametrize("env_id,limit", [("Reacher-v5", 50), ("Pusher-v5", 100)])
def test_reaching_tasks_match_gymnasium_over_episodes(env_id: str, limit: int) -> None:
    """Random actions on 3 slots for two episodes and a half, each slot reset (its own generator: Reacher's goal,
    Pusher's cylinder) at Gymnasium's time limit: every reset and step observation and reward equal Gymnasium's
    bit for bit, no episode terminates, both truncate together, and every reward term is nonzero on some step."""
    count = 3
    env, envs = paired_envs(env_id, count, seed=7)
    truncations, terms, active = 0, set(), set()
    for action in random_actions(envs[0], count, limit * 5 // 2):
        _, reward, terminated, truncated = env.step_slots(action)
        for i, genv in enumerate(envs):
            o, r, gym_terminated, gym_truncated, info = genv.step(action[i])
            np.testing.assert_array_equal(env._obs[i], o)
            assert env._reward[i] == r and reward[i].item() == np.float32(r)
            assert not terminated[i] and not gym_terminated and bool(truncated[i]) == gym_truncated
            reported, nonzero = reward_terms(info)
            terms, active = terms | reported, active | nonzero
        if truncated.any():
            assert truncated.all()
            truncations += 1
            env.reset()
            np.testing.assert_array_equal(env._obs, np.stack([genv.reset()[0] for genv in envs]))
    assert truncations == 2 and {"reward_dist", "reward_ctrl"} <= terms and active == terms
    env.close()


def test_terminated_slot_stays_out_while_others_run() -> None:
    """A slot left out of the step mask after its termination keeps its state and reports no reward, while the
    elapsed-step counter counts only the steps each slot ran."""
    env = MujocoBatchEnv("Hopper-v5", 2)
    env.set_seed(0)
    env.reset()
    action = np.ones((2, 3), dtype=np.float32)
    steps, terminated = 0, torch.zeros(2, dtype=torch.bool)
    while not terminated.any():
        _, _, terminated, _ = env.step_slots(action)
        steps += 1
    assert terminated.tolist() == [True, False] and 1 < steps < 200
    frozen = env._obs[0].copy()
    _, reward, terminated, _ = env.step_slots(action[1:], np.array([1]))
    np.testing.assert_array_equal(env._obs[0], frozen)
    assert reward[0] == 0 and terminated[0] and env._elapsed.tolist() == [steps, steps + 1]


@pytest.mark.parametrize(
    "env_id,steps",
    [
        ("Hopper-v5", 200),
        ("Walker2d-v5", 200),
        ("Ant-v5", 60),
        ("Humanoid-v5", 60),
        ("InvertedPendulum-v5", 200),
        ("InvertedDoublePendulum-v5", 200),
    ],
)
def test_terminating_spn_returns_match_gymnasium_backend(env_id: str, steps: int) -> None:
    """Early-terminating episodes of 3 SPNs on 4 slots through PopulationEvaluator: the same returns (bit for bit)
    and env steps on both backends, the steps counting only the steps each episode ran."""
    ref, got = spn_results_on_both_backends(env_id, steps)
    assert torch.equal(got.steps, ref.steps) and torch.equal(got.returns, ref.returns)
    assert torch.equal(got.spikes, ref.spikes)
    assert got.total_steps == int(got.steps.sum()) < 3 * steps  # some episode ended early
    assert ref.returns.std() > 0
