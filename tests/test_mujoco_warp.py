"""The mujoco_warp backend (MuJoCo Warp, float32) against MuJoCo C (float64): resets, steps and episode returns.

Warp's float32 cannot reproduce MuJoCo C's float64 bit for bit, so the tests state tolerances:
- Swimmer is not chaotic over short horizons: its steps agree to float32 rounding (1e-4 on the observation).
- HalfCheetah is: MuJoCo C started from the same state rounded to float32 (a 1e-8 relative change) drifts from
  itself by a factor of about 10 every 5 env steps (0.25 s of simulated time), so the bound on Warp's
  difference grows at that rate from 3e-5 (observation) and 3e-6 (reward) at step 0.
- HumanoidStandup: Warp uses the Newton solver (it has no PGS), so its reference is MuJoCo C with Newton.
- Episode returns (slow): for HalfCheetah the per-genome differences are float32 chaos, of the same size as
  MuJoCo C's own from a float32-rounded start (paired standard deviation about 10 over 100 steps), so the test
  is statistical: the paired t statistic below 3.5 (two-sided 1% for 7 degrees of freedom) and the difference of
  the mean returns below half the spread of the returns between genomes.

``SPN_WARP_DEVICE=cuda`` runs the same tests on a GPU (benchmarks/gpu_check.sh).
"""

from __future__ import annotations

import os

import gymnasium as gym
import mujoco
import numpy as np
import pytest
import torch
from tensordict import TensorDict

from spn_torchrl.envs import task_spec
from spn_torchrl.envs.mujoco import MujocoBatchEnv
from spn_torchrl.errors import ConfigError
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import PopulationSPN, init_fixed_weights

pytest.importorskip("mujoco_warp")
import spn_torchrl.envs.mujoco_warp as warp_module  # noqa: E402
from spn_torchrl.envs.mujoco_warp import MujocoWarpEnv, mujoco_warp_backend  # noqa: E402

DEVICE = os.environ.get("SPN_WARP_DEVICE", "cpu")
SLOTS = 4
SEEDS = [11, 12, 13, 14]


@pytest.fixture(scope="module")
def warp_env():
    """One Warp env of SLOTS worlds per task for the whole module (building one loads its compiled kernels)."""
    envs: dict[str, MujocoWarpEnv] = {}

    def get(env_id: str) -> MujocoWarpEnv:
        if env_id not in envs:
            envs[env_id] = mujoco_warp_backend(env_id, SLOTS, device=DEVICE)
        return envs[env_id]

    yield get
    for env in envs.values():
        env.close()


def controls(model: mujoco.MjModel, steps: int) -> np.ndarray:
    """Fixed random controls [steps, SLOTS, nu] float32 within the control range."""
    low, high = model.actuator_ctrlrange.T
    return np.random.default_rng(0).uniform(low, high, size=(steps, SLOTS, model.nu)).astype(np.float32)


@pytest.mark.parametrize(
    "env_id,obs_tol,reward_tol,growth",
    [("Swimmer-v5", 1e-4, 1e-5, 1.0), ("HalfCheetah-v5", 3e-5, 3e-6, 10 ** (1 / 5))],
)
def test_steps_match_mujoco_batch(warp_env, env_id: str, obs_tol: float, reward_tol: float, growth: float) -> None:
    env, ref = warp_env(env_id), MujocoBatchEnv(env_id, SLOTS)
    obs = env.reset(seed=SEEDS)["observation"]
    assert torch.equal(obs.cpu(), ref.reset(seed=SEEDS)["observation"])  # the same float32 state
    worst_obs = worst_reward = 0.0
    for k, action in enumerate(controls(ref.model, 20)):
        obs, reward, terminated, truncated = env.step_slots_torch(torch.from_numpy(action).to(env.device))
        ref_obs, ref_reward, _, _ = ref.step_slots(action)
        obs_err = (obs.cpu() - ref_obs).abs().max().item()
        reward_err = (reward.cpu() - ref_reward).abs().max().item()
        assert obs_err <= obs_tol * growth**k, f"step {k}: observation differs by {obs_err}"
        assert reward_err <= reward_tol * growth**k, f"step {k}: reward differs by {reward_err}"
        assert not terminated.any() and not truncated.any()
        worst_obs, worst_reward = max(worst_obs, obs_err), max(worst_reward, reward_err)
    print(f"{env_id}: 20 steps, max |obs diff| {worst_obs:.2e}, max |reward diff| {worst_reward:.2e}")


def newton_gym_envs(env_id: str, seeds: list[int]) -> tuple[list[gym.Env], np.ndarray]:
    """Gymnasium envs (MuJoCo C) with the Newton solver, each reset with its seed."""
    envs = [gym.make(env_id) for _ in seeds]
    obs = []
    for env, seed in zip(envs, seeds):
        env.unwrapped.model.opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
        obs.append(env.reset(seed=seed)[0])
    return envs, np.stack(obs)


def test_humanoidstandup_matches_mujoco_newton(warp_env) -> None:
    env_id = "HumanoidStandup-v5"
    env = warp_env(env_id)
    assert env.model.opt.solver == mujoco.mjtSolver.mjSOL_NEWTON  # the override PGS -> Newton
    obs = env.reset(seed=SEEDS)["observation"].cpu().numpy()
    envs, ref_obs = newton_gym_envs(env_id, SEEDS)
    np.testing.assert_allclose(obs, ref_obs, rtol=1e-5, atol=1e-5)
    # qpos[2:] | qvel | cinert | cvel | qfrc_actuator | cfrc_ext: contact forces (up to ~1e3) get their own bound
    parts = {"kinematics": (slice(0, 270), 3e-4), "cfrc_ext": (slice(270, 348), 0.1)}
    worst = dict.fromkeys(parts, 0.0) | {"reward": 0.0}
    impact_seen = False
    for action in controls(env.model, 10):
        obs, reward, _, _ = env.step_slots_torch(torch.from_numpy(action).to(env.device))
        obs, reward = obs.cpu().numpy(), reward.cpu().numpy()
        results = [genv.step(action[i]) for i, genv in enumerate(envs)]
        ref_obs = np.stack([r[0] for r in results])
        for name, (cols, tol) in parts.items():
            err = np.abs(obs[:, cols] - ref_obs[:, cols]).max()
            assert err <= tol, f"{name} differs by {err}"
            worst[name] = max(worst[name], err)
        err = np.abs(reward - np.array([r[1] for r in results])).max()
        assert err <= 1e-3
        worst["reward"] = max(worst["reward"], err)
        impact_seen |= any(r[4]["reward_impact"] < 0 for r in results)
    assert impact_seen  # contact forces entered the reward: the comparison has teeth
    print(f"{env_id} vs MuJoCo C (Newton), 10 steps: " + ", ".join(f"{k} {v:.2e}" for k, v in worst.items()))


@pytest.mark.parametrize("env_id", ["HalfCheetah-v5", "Swimmer-v5", "HumanoidStandup-v5"])
def test_seeded_slot_starts_as_mujoco_batch(warp_env, env_id: str) -> None:
    env, ref = warp_env(env_id), MujocoBatchEnv(env_id, SLOTS)
    seeds = [7, 0, 2**31 - 1, 7]
    obs, ref_obs = env.reset(seed=seeds)["observation"].cpu(), ref.reset(seed=seeds)["observation"]
    k = ref.model.nq - ref.task.skipped_qpos + ref.model.nv  # qpos and qvel: the drawn state, to float32
    assert torch.equal(obs[:, :k], ref_obs[:, :k])
    torch.testing.assert_close(obs, ref_obs, rtol=1e-5, atol=1e-5)  # derived fields computed in float32
    assert torch.equal(obs[0], obs[3]) and not torch.equal(obs[0], obs[1])
    env.set_seed(5)  # slot i seeded with 5 + i, then a reset draws each slot's second state
    ref.set_seed(5)
    assert torch.equal(env.reset()["observation"].cpu()[:, :k], ref.reset()["observation"][:, :k])


def test_masks_reset_and_freeze_slots(warp_env) -> None:
    env_id = "HalfCheetah-v5"
    env, ref = warp_env(env_id), MujocoBatchEnv(env_id, SLOTS)
    env.reset(seed=SEEDS)
    ref.reset(seed=SEEDS)
    before = env._obs.cpu().clone()
    mask = torch.tensor([False, True, False, False])
    td = env.reset(TensorDict({"_reset": mask[:, None].to(env.device)}, batch_size=[SLOTS]))
    ref.reset(TensorDict({"_reset": mask[:, None]}, batch_size=[SLOTS]))  # the slot's next draw
    obs = env._obs.cpu()  # TorchRL's partial reset returns only the reset rows' observations
    assert torch.equal(obs[1], torch.from_numpy(ref._obs[1]).float()) and not torch.equal(obs[1], before[1])
    assert torch.equal(obs[[0, 2, 3]], before[[0, 2, 3]])
    td["action"] = torch.full((SLOTS, 6), 0.3, device=env.device)
    td["_step"] = torch.tensor([True, True, False, True], device=env.device)
    qpos = env.qpos.cpu().clone()
    nxt = env.step(td)["next"]
    assert torch.equal(nxt["observation"][2].cpu(), obs[2]) and nxt["reward"][2, 0] == 0
    assert torch.equal(env.qpos.cpu()[2], qpos[2]) and not torch.equal(env.qpos.cpu()[0], qpos[0])
    assert env._elapsed.tolist() == [1, 1, 0, 1]


def test_time_limit_truncates_at_1000_steps(warp_env) -> None:
    env = warp_env("Swimmer-v5")
    env.reset(seed=SEEDS)
    env._elapsed[:] = 998  # the counter, not 998 steps of physics
    zeros = torch.zeros(SLOTS, 2, device=env.device)
    assert not env.step_slots_torch(zeros)[3].any()
    terminated, truncated = env.step_slots_torch(zeros)[2:]
    assert truncated.all() and not terminated.any()


def test_capacity_overflow_is_an_error(monkeypatch) -> None:
    """Too small a contact and constraint capacity: Warp drops contacts, and the episode is refused."""
    monkeypatch.setitem(warp_module.WARP_SIZES, "HalfCheetah-v5", warp_module.WarpSizes(nconmax=1, njmax=4))
    env = mujoco_warp_backend("HalfCheetah-v5", 2, device=DEVICE)
    env.reset(seed=[0, 1])
    for _ in range(30):  # the cheetah settles on the floor with several contacts
        env.step_slots_torch(torch.full((2, 6), 0.5, device=env.device))
    with pytest.raises(RuntimeError, match="overflowed its per-world capacity"):
        env.check_overflow()


def test_config_errors() -> None:
    with pytest.raises(ConfigError, match="mujoco_warp supports"):
        mujoco_warp_backend("Hopper-v5", 2)
    with pytest.raises(ConfigError, match="env.threads must be 1"):
        mujoco_warp_backend("Swimmer-v5", 2, threads=2)
    with pytest.raises(ConfigError, match="env.device must be"):
        mujoco_warp_backend("Swimmer-v5", 2, device="tpu")
    if not torch.cuda.is_available():
        with pytest.raises(ConfigError, match="no CUDA device"):
            mujoco_warp_backend("Swimmer-v5", 2, device="cuda")


def spn_and_genomes(env_id: str, count: int) -> tuple[PopulationSPN, torch.Tensor]:
    spec = task_spec(env_id)
    gen = torch.Generator().manual_seed(1)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, 64, gen)
    spn = PopulationSPN(w1, w2, action_low=spec.action_low, action_high=spec.action_high)
    return spn, torch.randn(count, spn.genome_size, generator=gen)


@pytest.mark.slow
@pytest.mark.parametrize("env_id,steps", [("HalfCheetah-v5", 100), ("HumanoidStandup-v5", 100)])
def test_spn_returns_agree_statistically(env_id: str, steps: int) -> None:
    """8 SPN genomes on 9 slots (an idle one) through PopulationEvaluator on both backends, seeds 123 + i.
    HumanoidStandup's reference keeps Gymnasium's PGS: the difference includes Newton's."""
    torch.set_num_threads(1)
    spn, genomes = spn_and_genomes(env_id, 8)
    results = {}
    for name, env in (
        ("warp", mujoco_warp_backend(env_id, 9, device=DEVICE)),
        ("batch", MujocoBatchEnv(env_id, 9)),
    ):
        evaluator = PopulationEvaluator(env, spn, steps)
        results[name] = evaluator(genomes, 123)
        evaluator.close()
    warp, ref = results["warp"], results["batch"]
    assert warp.returns.device.type == "cpu" and torch.equal(warp.steps, ref.steps) and warp.total_steps == 8 * steps
    diff = (warp.returns - ref.returns).double()
    t = diff.mean() / (diff.std() / len(diff) ** 0.5)
    spread = ref.returns.double().std()
    print(
        f"{env_id}, {steps} steps: mean return warp {warp.returns.mean():.2f} mujoco_batch {ref.returns.mean():.2f}, "
        f"paired t {t:.2f}, |mean diff| / between-genome std {diff.mean().abs() / spread:.3f}, "
        f"paired diff std {diff.std():.3f}"
    )
    assert abs(t) < 3.5
    assert diff.mean().abs() < 0.5 * spread
    torch.testing.assert_close(warp.spikes, ref.spikes, rtol=0.05, atol=0)  # the same policies, near states


@pytest.mark.slow
@pytest.mark.parametrize("env", ["halfcheetah", "swimmer", "humanoidstandup"])
def test_a_tiny_train_run_on_warp_completes(tmp_path, env):
    from conftest import run_train

    from spn_torchrl.records import read_progress

    tiny = ["algo.generations=1", "algo.population=2", "algo.elite_candidates=1", "algo.elite_episodes=1"]
    run_train(tmp_path, f"env={env}", "env.backend=mujoco_warp", "env.device=cpu", "env.threads=1", *tiny)
    (row,) = read_progress(tmp_path / "progress.csv")
    # 2 individuals and 1 re-evaluation episode, each to the 1000-step limit (these tasks never terminate)
    assert row["generation"] == 1 and row["env_steps"] == 3 * 1000 and np.isfinite(row["eval_return"])
