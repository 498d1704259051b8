"""``env.backend=mujoco_batch_mj210``: mujoco_batch's Gymnasium v5 tasks with the body inertias that MuJoCo 2.1.0
(the paper's simulator) compiles from the same bodies.

MuJoCo 2.1.0 compiles other ``body_mass``, ``body_inertia``, ``body_ipos`` and ``body_iquat`` than MuJoCo 4.0 from
the tasks' geoms (Swimmer's segments 34.56 against 35.60, HalfCheetah's torso 6.360 against 6.250). This backend
loads the v5 model, writes MuJoCo 2.1.0's four arrays into it (``data/mujoco210_inertia.json``, written by
``scripts/dump_mujoco210_inertia.py`` in the gym_v2 venv, with its provenance) and recomputes the constants that
derive from them (``mj_setConst``); the rest is :class:`~spn_torchrl.envs.mujoco.MujocoBatchEnv`. An option beyond
the paper, off by default: env.backend=mujoco_batch is the v5 model as MuJoCo 4.0 compiles it.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path

import mujoco
import numpy as np
from gymnasium.envs.mujoco.mujoco_env import expand_model_path

from spn_torchrl.envs.mujoco import MujocoBatchEnv, batch_task
from spn_torchrl.errors import ConfigError

DATA = Path(__file__).with_name("data") / "mujoco210_inertia.json"
FIELDS = ("body_mass", "body_inertia", "body_ipos", "body_iquat")
MJ210_TASKS = {"HalfCheetah-v5": "HalfCheetah-v2", "Swimmer-v5": "Swimmer-v2"}  # v5 id: the v2 task dumped


@functools.cache
def mujoco210_data() -> dict:
    """The dumped arrays and their provenance (``provenance``, ``tasks`` by v2 id)."""
    return json.loads(DATA.read_text())


def mujoco210_model(env_id: str) -> mujoco.MjModel:
    """The v5 model of ``env_id`` with MuJoCo 2.1.0's compiled body inertias."""
    if env_id not in MJ210_TASKS:
        raise ConfigError(f"env.backend=mujoco_batch_mj210 steps {', '.join(MJ210_TASKS)}, not env.id={env_id!r}")
    record = mujoco210_data()["tasks"][MJ210_TASKS[env_id]]
    model = mujoco.MjModel.from_xml_path(expand_model_path(batch_task(env_id).xml))
    names = [model.body(i).name for i in range(model.nbody)]
    if names != record["body_names"]:
        raise ConfigError(f"{DATA}: {env_id} has bodies {names}, the dumped MuJoCo 2.1.0 model {record['body_names']}")
    for field in FIELDS:
        getattr(model, field)[:] = np.asarray(record[field], dtype=np.float64)
    mujoco.mj_setConst(model, mujoco.MjData(model))
    return model


def mujoco210_backend(env_id: str, num_envs: int, threads: int = 1) -> MujocoBatchEnv:
    """Backend factory: mujoco_batch on :func:`mujoco210_model`, ``threads`` physics threads."""
    return MujocoBatchEnv(env_id, num_envs, num_threads=threads, model=mujoco210_model(env_id))
