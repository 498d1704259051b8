"""The cartpole_batch backend against Gymnasium's CartPole-v1: same resets, steps, ends and episode returns."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from tensordict import TensorDict

from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.envs.cartpole import CartPoleBatchEnv
from spn_torchrl.errors import ConfigError
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import PopulationSPN, init_fixed_weights


def test_steps_resets_and_ends_match_gymnasium() -> None:
    """Random actions for 400 steps on 8 copies, each reset when it ends: every observation, reward and flag
    equals Gymnasium's, bit for bit (including the float32 observation)."""
    count, seed = 8, 3
    env = CartPoleBatchEnv(count, max_episode_steps=60)
    env.set_seed(seed)
    td = env.reset()
    envs = [gym.make("CartPole-v1", max_episode_steps=60) for _ in range(count)]
    for i, genv in enumerate(envs):
        genv.reset(seed=seed + i)
    ref = np.stack([genv.reset()[0] for genv in envs])  # set_seed resets once, TorchRL's reset() again
    np.testing.assert_array_equal(td["observation"].numpy(), ref)
    rng = np.random.default_rng(0)
    ends = {"terminated": 0, "truncated": 0}
    for _ in range(400):
        action = rng.integers(0, 2, size=count)
        td["action"] = torch.from_numpy(action)
        stepped, td = env.step_and_maybe_reset(td)
        nxt = stepped["next"]
        for i, genv in enumerate(envs):
            o, r, terminated, truncated, _ = genv.step(int(action[i]))
            np.testing.assert_array_equal(nxt["observation"][i].numpy(), o)
            assert nxt["reward"][i, 0].item() == r
            assert (nxt["terminated"][i, 0].item(), nxt["truncated"][i, 0].item()) == (terminated, truncated)
            ends["terminated"] += terminated
            ends["truncated"] += truncated and not terminated
            if terminated or truncated:
                np.testing.assert_array_equal(td["observation"][i].numpy(), genv.reset()[0])
    assert ends["terminated"] > 10 and ends["truncated"] > 0  # both ends were compared


def test_step_mask_leaves_idle_slots_alone() -> None:
    env = CartPoleBatchEnv(3)
    env.set_seed(0)
    td = env.reset()
    before = td["observation"].clone()
    td["action"] = torch.tensor([1, 0, 1])
    td["_step"] = torch.tensor([True, False, True])
    nxt = env.step(td)["next"]
    assert torch.equal(nxt["observation"][1], before[1]) and not torch.equal(nxt["observation"][0], before[0])
    assert nxt["reward"].flatten().tolist() == [1.0, 0.0, 1.0] and env._elapsed.tolist() == [1, 0, 1]
    state = env._obs.copy()
    env.reset(TensorDict({"_reset": torch.tensor([[False], [False], [True]])}, batch_size=[3]))
    np.testing.assert_array_equal(env._obs[:2], state[:2])
    assert not np.array_equal(env._obs[2], state[2]) and env._elapsed.tolist() == [1, 0, 0]


def test_spn_returns_match_gymnasium_backend() -> None:
    """A population of SPNs, 30 genomes on 32 slots, through PopulationEvaluator on both backends."""
    torch.set_num_threads(1)
    spec = task_spec("CartPole-v1")
    gen = torch.Generator().manual_seed(2)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, 64, gen)
    spn = PopulationSPN(w1, w2, discrete=True)
    genomes = torch.randn(30, spn.genome_size, generator=gen)
    results = {}
    for backend in ("gymnasium", "cartpole_batch"):
        evaluator = PopulationEvaluator(
            make_batched_env("CartPole-v1", 32, backend=backend), spn, spec.max_episode_steps
        )
        results[backend] = evaluator(genomes, 7)
        evaluator.close()
    ref, got = results["gymnasium"], results["cartpole_batch"]
    assert torch.equal(got.returns, ref.returns) and torch.equal(got.steps, ref.steps)
    assert torch.equal(got.spikes, ref.spikes)
    assert len(ref.returns.unique()) > 3  # the genomes behave differently: the comparison has teeth


def test_other_ids_and_workers_are_config_errors() -> None:
    with pytest.raises(ConfigError, match="steps CartPole-v1 only"):
        make_batched_env("Acrobot-v1", 2, backend="cartpole_batch")
    with pytest.raises(ConfigError, match="env.threads must be 1"):
        make_batched_env("CartPole-v1", 2, backend="cartpole_batch", threads=2)
