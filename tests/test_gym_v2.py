"""env.backend=gym_v2: the missing venv's error, task specs and config without the venv; with it (built by
``bash scripts/make_gym_v2_env.sh``, as .ci/run does), the workers against Gym 0.21 itself and a tiny train.py
generation on each v2 task. The slow tests fail, not skip, where the venv is missing."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest
from conftest import run_train

from spn_torchrl import checkpoint
from spn_torchrl.envs import check_backend, make_batched_env, task_spec
from spn_torchrl.envs.gym_v2 import MAKE_COMMAND, V2_TASKS, VENV_VARIABLE, v2_python, v2_venv
from spn_torchrl.errors import ConfigError
from spn_torchrl.records import read_progress


def test_missing_venv_is_one_sentence_naming_the_command(monkeypatch, tmp_path):
    monkeypatch.setenv(VENV_VARIABLE, str(tmp_path / "nowhere"))
    with pytest.raises(ConfigError) as err:
        check_backend("gym_v2", "HalfCheetah-v2")
    message = str(err.value)
    assert MAKE_COMMAND in message and str(tmp_path / "nowhere") in message and "\n" not in message
    with pytest.raises(ConfigError, match="scripts/make_gym_v2_env.sh"):
        make_batched_env("Swimmer-v2", 2, backend="gym_v2")


def test_v2_ids_have_their_specs_and_other_backends_refuse_them():
    cheetah, swimmer = task_spec("HalfCheetah-v2"), task_spec("Swimmer-v2")
    assert (cheetah.n_obs, cheetah.n_act, cheetah.max_episode_steps) == (17, 6, 1000)
    assert (swimmer.n_obs, swimmer.n_act, swimmer.max_episode_steps) == (8, 2, 1000)
    assert not cheetah.discrete and float(cheetah.action_low.min()) == -1.0 and float(cheetah.action_high.max()) == 1.0
    with pytest.raises(ConfigError, match="env.backend=mujoco_batch steps"):
        check_backend("mujoco_batch", "HalfCheetah-v2")
    with pytest.raises(ConfigError, match="env.backend=gym_v2 steps"):
        check_backend("gym_v2", "HalfCheetah-v5")


def test_config_takes_worker_processes_for_gym_v2(make_config):
    cfg = make_config("env=halfcheetah_v2", "env.threads=4")
    assert (cfg.env.id, cfg.env.backend, cfg.env.threads) == ("HalfCheetah-v2", "gym_v2", 4)
    with pytest.raises(ConfigError, match="env.threads"):
        make_config("env=cartpole", "env.threads=2")


def venv_python() -> str:
    """The gym_v2 venv's python; the test FAILS (not skips) without it."""
    try:
        return str(v2_python())
    except ConfigError as err:
        pytest.fail(f"{err} (.ci/run builds it)")


GYM_EPISODE = """
import json, sys
import gym, numpy as np
env_id, seed, steps = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
env = gym.make(env_id)
env.seed(seed)
obs = [env.reset().tolist()]
actions = np.random.default_rng(seed).uniform(-1, 1, (steps, env.action_space.shape[0])).astype(np.float32)
rewards = []
for a in actions:
    o, r, done, _ = env.step(a * env.action_space.high)
    obs.append(o.tolist()); rewards.append(r)
print(json.dumps({"obs": obs, "rewards": rewards}))
"""


@pytest.mark.slow
@pytest.mark.parametrize("env_id", ["HalfCheetah-v2", "Swimmer-v2"])
def test_workers_step_as_gym_0_21_seeded_with_env_seed(env_id):
    python, steps, seeds = venv_python(), 200, [3, 11, 12]
    spec = task_spec(env_id)
    env = make_batched_env(env_id, len(seeds), backend="gym_v2", threads=2)  # slots 0-1 on one worker, 2 on another
    try:
        assert {k: env.versions[k] for k in ("gym", "mj_version", "free_mujoco_py")} == {
            "gym": "0.21.0",
            "mj_version": 210,
            "free_mujoco_py": "2.1.6",
        }
        obs = [env.reset(seed=seeds)["observation"].double().numpy()]
        actions = [np.random.default_rng(s).uniform(-1, 1, (steps, spec.n_act)).astype(np.float32) for s in seeds]
        rewards = []
        for t in range(steps):
            o, r, _, truncated = env.step_slots(np.stack([a[t] for a in actions]))
            obs.append(o.double().numpy())
            rewards.append(r.double().numpy())
        assert not truncated.any()
    finally:
        env.close()
    for i, s in enumerate(seeds):
        out = subprocess.run(
            [python, "-c", GYM_EPISODE, env_id, str(s), str(steps)], capture_output=True, text=True, check=True
        )
        ref = json.loads(out.stdout)
        # the env's float32 observations and rewards, from Gym's float64 ones
        np.testing.assert_allclose([o[i] for o in obs], ref["obs"], rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose([r[i] for r in rewards], ref["rewards"], rtol=1e-6, atol=1e-5)


@pytest.mark.slow
def test_workers_report_the_v2_task_specs():
    venv_python()
    for env_id, task in V2_TASKS.items():
        env = make_batched_env(env_id, 1, backend="gym_v2")
        try:
            info = env._workers[0].info
            assert (info["n_obs"], info["n_act"], info["max_episode_steps"]) == (task.n_obs, task.n_act, 1000)
            bound = np.full(task.n_act, task.action_bound, dtype=np.float32)  # Gym's float32 Box
            np.testing.assert_array_equal(np.float32(info["action_low"]), -bound)
            np.testing.assert_array_equal(np.float32(info["action_high"]), bound)
        finally:
            env.close()


@pytest.mark.slow
@pytest.mark.parametrize("env", ["halfcheetah_v2", "swimmer_v2"])
def test_tiny_generation_on_each_v2_task(tmp_path, env):
    venv_python()
    run_train(
        tmp_path,
        f"env={env}",
        "algo=conn_ga",
        "algo.generations=1",
        "algo.population=4",
        "algo.elite_candidates=1",
        "algo.elite_episodes=2",
        "evaluator.processes=2",
        "torch_threads=1",
    )
    rows = read_progress(tmp_path / "progress.csv")
    assert [r["generation"] for r in rows] == [1]
    assert rows[0]["env_steps"] == (4 + 2) * 1000  # no v2 task terminates: every episode runs 1000 steps
    state = checkpoint.load(tmp_path)
    assert state["meta"]["env_id"] == {"halfcheetah_v2": "HalfCheetah-v2", "swimmer_v2": "Swimmer-v2"}[env]
    assert v2_venv().is_dir()
