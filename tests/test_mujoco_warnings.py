"""MuJoCo's warnings go to the ``mujoco`` logger, not to the terminal and ``./MUJOCO_LOG.TXT``; the known
``settotalmass`` one of Gymnasium's models is logged at DEBUG and the compiled model is unchanged."""

from __future__ import annotations

import logging
import os
import subprocess

import mujoco
import numpy as np
import pytest
from conftest import train_command
from gymnasium.envs.mujoco.mujoco_env import expand_model_path

from spn_torchrl.envs.mujoco import SETTOTALMASS, mujoco_warning


def test_importing_the_envs_installs_the_handler():
    assert mujoco.get_mju_user_warning() is mujoco_warning


def test_warnings_reach_the_mujoco_logger_and_no_log_file(tmp_path, monkeypatch, caplog):
    monkeypatch.chdir(tmp_path)
    caplog.set_level(logging.DEBUG, logger="mujoco")
    model = mujoco.MjModel.from_xml_path(expand_model_path("half_cheetah.xml"))
    data = mujoco.MjData(model)
    data.qpos[0] = np.nan
    mujoco.mj_step(model, data)
    levels = {r.levelno: r.getMessage() for r in caplog.records if r.name == "mujoco"}
    assert levels[logging.DEBUG].startswith(SETTOTALMASS)
    assert levels[logging.WARNING].startswith("Nan, Inf or huge value in QPOS at DOF 0")
    assert model.body_mass.sum() == pytest.approx(14.0)  # settotalmass still applies
    assert list(tmp_path.iterdir()) == []  # no MUJOCO_LOG.TXT


@pytest.mark.slow
def test_a_halfcheetah_run_prints_no_mujoco_warning(tmp_path):
    """The run's process and its two evaluator workers each compile the model."""
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    overrides = ["env=halfcheetah", "algo.generations=1", "algo.population=4", "algo.elite_candidates=1"]
    overrides += ["algo.elite_episodes=1", "evaluator.processes=2", "torch_threads=1"]
    done = subprocess.run(
        train_command(tmp_path / "run", *overrides), cwd=tmp_path, env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert "WARNING: compiler" not in done.stdout + done.stderr
    assert "settotalmass" not in done.stdout + done.stderr
    assert [p.name for p in tmp_path.iterdir()] == ["run"]  # no MUJOCO_LOG.TXT in the working directory
