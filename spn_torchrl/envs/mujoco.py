"""A TorchRL env of P copies of a Gymnasium v5 MuJoCo task, stepped in one ``mujoco.batch.Batch`` call.

Replicates Gymnasium v5 (default kwargs) of HalfCheetah, Swimmer and HumanoidStandup: observation, reward
terms, reset distribution and seeding, frame skip and the 1000-step time limit (truncation); slots, seeding and
masks as :class:`~spn_torchrl.envs.batch.BatchEnv`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import mujoco
import numpy as np
import torch
from gymnasium.envs.mujoco.mujoco_env import expand_model_path
from mujoco.batch import Batch
from torchrl.data import Bounded
from torchrl.envs import EnvBase

from spn_torchrl.envs.batch import BatchEnv, rows
from spn_torchrl.errors import ConfigError


@dataclass(frozen=True)
class BatchTask:
    """What differs between the supported Gymnasium v5 tasks (their default kwargs)."""

    xml: str
    frame_skip: int
    reset_noise_scale: float
    qvel_noise: str  # "normal" (scaled standard normal) or "uniform"
    skipped_qpos: int
    ctrl_cost_weight: float
    standup: bool = False  # HumanoidStandup: com-based observation, up-height reward, impact cost
    max_episode_steps: int = 1000


BATCH_TASKS: dict[str, BatchTask] = {
    "HalfCheetah-v5": BatchTask("half_cheetah.xml", 5, 0.1, "normal", 1, 0.1),
    "Swimmer-v5": BatchTask("swimmer.xml", 4, 0.1, "uniform", 2, 1e-4),
    "HumanoidStandup-v5": BatchTask("humanoidstandup.xml", 5, 1e-2, "uniform", 2, 0.1, standup=True),
}
IMPACT_COST_WEIGHT = 0.5e-6
IMPACT_COST_MAX = 10.0


def batch_task(env_id: str, backend: str = "mujoco_batch") -> BatchTask:
    """The task definition of a supported id; ConfigError naming ``backend`` for any other."""
    if env_id not in BATCH_TASKS:
        raise ConfigError(
            f"env.backend={backend} supports {', '.join(BATCH_TASKS)}, not {env_id!r}: "
            "use env.backend=gymnasium for other tasks"
        )
    return BATCH_TASKS[env_id]


def observation_size(model: mujoco.MjModel, task: BatchTask) -> int:
    """Length of Gymnasium v5's observation of a task."""
    size = model.nq - task.skipped_qpos + model.nv
    if task.standup:
        size += (model.nbody - 1) * (10 + 6 + 6) + (model.nv - 6)
    return size


def initial_state(task: BatchTask, model: mujoco.MjModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Gymnasium v5's reset draw of a task from a slot's generator: qpos [nq] and qvel [nv], float64."""
    scale = task.reset_noise_scale
    qpos = model.qpos0 + rng.uniform(low=-scale, high=scale, size=model.nq)
    if task.qvel_noise == "normal":
        qvel = np.zeros(model.nv) + scale * rng.standard_normal(model.nv)
    else:
        qvel = np.zeros(model.nv) + rng.uniform(low=-scale, high=scale, size=model.nv)
    return qpos, qvel


class MujocoBatchEnv(BatchEnv):
    """P simulations of one task on ``num_threads`` MuJoCo threads, as a TorchRL env of batch size [P]."""

    def __init__(self, env_id: str, num_envs: int, num_threads: int = 1) -> None:
        task = batch_task(env_id)
        self.env_id = env_id
        self.task = task
        self.model = mujoco.MjModel.from_xml_path(expand_model_path(task.xml))
        m = self.model
        p = num_envs
        low = torch.as_tensor(m.actuator_ctrlrange[:, 0], dtype=torch.float32)
        high = torch.as_tensor(m.actuator_ctrlrange[:, 1], dtype=torch.float32)
        action_spec = Bounded(low.expand(p, m.nu), high.expand(p, m.nu), shape=(p, m.nu), dtype=torch.float32)
        super().__init__(num_envs, observation_size(m, task), action_spec, task.max_episode_steps)
        # a persistent batch keeps each simulation's MjData, whose contact forces HumanoidStandup needs
        self.batch = Batch(m, num_envs, nthread=num_threads, persistent=task.standup)
        self.qpos, self.qvel, self.ctrl = self.batch.bind("qpos"), self.batch.bind("qvel"), self.batch.bind("ctrl")
        self.dt = m.opt.timestep * task.frame_skip
        if task.standup:
            self.cinert, self.cvel = self.batch.bind("cinert"), self.batch.bind("cvel")
            self.qfrc_actuator = self.batch.bind("qfrc_actuator")
            self.cfrc_ext = np.zeros((p, m.nbody, 6))
            self._scratch = mujoco.MjData(m)
        self._x_before = np.zeros(p)
        self.physics_seconds = 0.0  # wall time inside the batched physics call (benchmarks read it)

    def _write_obs(self, ids: np.ndarray | None) -> None:
        """Gymnasium's ``_get_obs`` for the rows ``ids`` (None: all) into the observation buffer."""
        slots = rows(ids)
        m, task = self.model, self.task
        k = task.skipped_qpos
        parts = [self.qpos[slots, k:], self.qvel[slots]]
        if task.standup:
            parts += [
                self.cinert[slots, 1:].reshape(-1, (m.nbody - 1) * 10),
                self.cvel[slots, 1:].reshape(-1, (m.nbody - 1) * 6),
                self.qfrc_actuator[slots, 6:],
                self.cfrc_ext[slots, 1:].reshape(-1, (m.nbody - 1) * 6),
            ]
        if ids is None:
            np.concatenate(parts, axis=1, out=self._obs)
        else:
            self._obs[ids] = np.concatenate(parts, axis=1)

    def _contact_forces(self, ids: np.ndarray | None) -> None:
        """Gymnasium's ``mj_rnePostConstraint`` after each step: external contact forces per body."""
        data = self._scratch
        for sim in self._all[rows(ids)]:
            self.batch.get_data(int(sim), data)
            mujoco.mj_rnePostConstraint(self.model, data)
            self.cfrc_ext[sim] = data.cfrc_ext

    def _reset_slots(self, ids: np.ndarray | None) -> None:
        task = self.task
        self.batch.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        for sim in self._all[rows(ids)]:
            self.qpos[sim], self.qvel[sim] = initial_state(task, self.model, self._rngs[sim])
        self.batch.forward(ids)
        if task.standup:
            self.cfrc_ext[rows(ids)] = 0.0  # mj_resetData clears it and mj_forward does not compute it
        self._write_obs(ids)

    def _advance(self, ids: np.ndarray | None, action: np.ndarray) -> None:
        slots = rows(ids)
        task = self.task
        self.ctrl[slots] = action
        if not task.standup:
            self._x_before[slots] = self.qpos[slots, 0]
        t0 = time.perf_counter()
        self.batch.step(ids, nstep=task.frame_skip)
        self.physics_seconds += time.perf_counter() - t0
        if task.standup:
            self._contact_forces(ids)
            uph = self.qpos[slots, 2] / self.model.opt.timestep
            quad_ctrl = task.ctrl_cost_weight * np.square(self.ctrl[slots]).sum(-1)
            impact = np.minimum(
                IMPACT_COST_WEIGHT * np.square(self.cfrc_ext[slots]).reshape(len(uph), -1).sum(-1), IMPACT_COST_MAX
            )
            self._reward[slots] = uph - quad_ctrl - impact + 1
        else:
            # float32 action -> float32 control cost, as Gymnasium computes it on the action it is given
            ctrl_cost = task.ctrl_cost_weight * np.square(action).sum(-1)
            self._reward[slots] = (self.qpos[slots, 0] - self._x_before[slots]) / self.dt - ctrl_cost
        self._write_obs(ids)


def mujoco_batch_backend(env_id: str, num_envs: int, threads: int = 1) -> EnvBase:
    """Backend factory: ``threads`` physics threads."""
    return MujocoBatchEnv(env_id, num_envs, num_threads=threads)
