"""TorchRL envs of P copies of a Gymnasium v5 MuJoCo task, stepped on C threads.

Replicates Gymnasium v5 (default kwargs) of HalfCheetah, Swimmer and HumanoidStandup, of the locomotion tasks
Hopper, Walker2d, Ant and Humanoid, of InvertedPendulum and InvertedDoublePendulum, and of Reacher and Pusher (their
terms in :mod:`spn_torchrl.envs.mujoco_tasks`, with the termination of each): observation, reward terms, reset
distribution and seeding, frame skip and the time limit (truncation at 1000 steps; Reacher's 50, Pusher's 100);
slots, seeding and masks as :class:`~spn_torchrl.envs.batch.BatchEnv`. Most tasks step in one
``mujoco.batch.Batch`` call; HumanoidStandup, Ant and Humanoid, whose observation and reward read the contact forces
that ``mj_rnePostConstraint`` computes after every step, step one ``MjData`` per simulation on a thread pool
(:class:`DataSimulations`), so that the call runs in place.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import mujoco
import numpy as np
import torch
from gymnasium.envs.mujoco.mujoco_env import expand_model_path
from mujoco.batch import Batch
from torchrl.data import Bounded
from torchrl.envs import EnvBase

from spn_torchrl.envs.batch import BatchEnv, rows
from spn_torchrl.envs.mujoco_tasks import (
    ANT,
    HOPPER,
    HUMANOID,
    INVERTED_DOUBLE_PENDULUM,
    INVERTED_PENDULUM,
    PUSHER,
    REACHER,
    WALKER2D,
    Terms,
    com_parts,
)
from spn_torchrl.errors import ConfigError

# Gymnasium's MuJoCo XMLs (half_cheetah.xml ...) set <compiler settotalmass=...>: MuJoCo 4 warns that the attribute is
# deprecated and still applies it, so the compiled model (total mass included) is the one Gymnasium steps
SETTOTALMASS = "compiler attribute 'settotalmass' is deprecated"
mujoco_log = logging.getLogger("mujoco")


def mujoco_warning(message: str) -> None:
    """MuJoCo's warnings go to the ``mujoco`` logger (the run's log), not to the terminal and ``./MUJOCO_LOG.TXT``
    (MuJoCo's own handler); the known ``settotalmass`` one, once per compiled model, at DEBUG."""
    if message.startswith(SETTOTALMASS):
        mujoco_log.debug(message)
    else:
        mujoco_log.warning(message)


mujoco.set_mju_user_warning(mujoco_warning)  # process-wide: every process that imports spn_torchrl.envs


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
    terms: Terms | None = None  # a task with its own observation, reward and termination (envs/mujoco_tasks.py)


BATCH_TASKS: dict[str, BatchTask] = {
    "HalfCheetah-v5": BatchTask("half_cheetah.xml", 5, 0.1, "normal", 1, 0.1),
    "Swimmer-v5": BatchTask("swimmer.xml", 4, 0.1, "uniform", 2, 1e-4),
    "HumanoidStandup-v5": BatchTask("humanoidstandup.xml", 5, 1e-2, "uniform", 2, 0.1, standup=True),
    # the locomotion tasks (hopper_v5.py, walker2d_v5.py, ant_v5.py, humanoid_v5.py): terms in envs/mujoco_tasks.py
    "Hopper-v5": BatchTask("hopper.xml", 4, 5e-3, "uniform", 1, 1e-3, terms=HOPPER),
    "Walker2d-v5": BatchTask("walker2d_v5.xml", 4, 5e-3, "uniform", 1, 1e-3, terms=WALKER2D),
    "Ant-v5": BatchTask("ant.xml", 5, 0.1, "normal", 2, 0.5, terms=ANT),
    "Humanoid-v5": BatchTask("humanoid.xml", 5, 1e-2, "uniform", 2, 0.1, terms=HUMANOID),
    "InvertedPendulum-v5": BatchTask("inverted_pendulum.xml", 2, 0.01, "uniform", 0, 0.0, terms=INVERTED_PENDULUM),
    "InvertedDoublePendulum-v5": BatchTask(
        "inverted_double_pendulum.xml", 5, 0.1, "normal", 0, 0.0, terms=INVERTED_DOUBLE_PENDULUM
    ),
    # reacher_v5.py, pusher_v5.py: their own reset draws (terms.reset), so no noise scale; 50 and 100 steps an episode
    "Reacher-v5": BatchTask("reacher.xml", 2, 0.0, "uniform", 0, 1.0, max_episode_steps=50, terms=REACHER),
    "Pusher-v5": BatchTask("pusher_v5.xml", 5, 0.0, "uniform", 0, 0.1, max_episode_steps=100, terms=PUSHER),
}
IMPACT_COST_WEIGHT = 0.5e-6
IMPACT_COST_MAX = 10.0
STANDUP_FIELDS = ("cinert", "cvel", "qfrc_actuator", "cfrc_ext")  # HumanoidStandup's observation beyond qpos, qvel
POST_CONSTRAINT_FIELDS = frozenset({"cacc", "cfrc_int", "cfrc_ext"})  # what mj_rnePostConstraint computes


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
    if task.terms is not None:
        return task.terms.size(model)
    size = model.nq - task.skipped_qpos + model.nv
    if task.standup:
        size += (model.nbody - 1) * (10 + 6 + 6) + (model.nv - 6)
    return size


def initial_state(task: BatchTask, model: mujoco.MjModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """Gymnasium v5's reset draw of a task from a slot's generator: qpos [nq] and qvel [nv], float64."""
    if task.terms is not None and task.terms.reset is not None:
        return task.terms.reset(model, rng)
    scale = task.reset_noise_scale
    qpos = model.qpos0 + rng.uniform(low=-scale, high=scale, size=model.nq)
    if task.qvel_noise == "normal":
        qvel = np.zeros(model.nv) + scale * rng.standard_normal(model.nv)
    else:
        qvel = np.zeros(model.nv) + rng.uniform(low=-scale, high=scale, size=model.nv)
    return qpos, qvel


class BatchSimulations:
    """P simulations in one ``mujoco.batch.Batch``: ``qpos``, ``qvel``, ``ctrl`` and the ``fields`` are live
    [P, ...] arrays (the fields describe the state before the last substep, as after ``mj_step``)."""

    def __init__(self, model: mujoco.MjModel, num_envs: int, threads: int, fields: tuple[str, ...] = ()) -> None:
        self.batch = Batch(model, num_envs, nthread=threads)
        self.qpos, self.qvel, self.ctrl = self.batch.bind("qpos"), self.batch.bind("qvel"), self.batch.bind("ctrl")
        for name in fields:
            setattr(self, name, self.batch.bind(name))

    def reset(self, ids: np.ndarray | None, qpos: np.ndarray, qvel: np.ndarray) -> None:
        """Gymnasium's reset of simulations ``ids`` (None: all) to the rows of ``qpos`` and ``qvel``."""
        self.batch.reset(ids, stage=mujoco.mjtStage.mjSTAGE_NONE)
        self.qpos[rows(ids)], self.qvel[rows(ids)] = qpos, qvel
        self.batch.forward(ids)

    def step(self, ids: np.ndarray | None, nstep: int) -> float:
        """``mj_step`` ``nstep`` times from ``ctrl``; returns the seconds of the physics."""
        t0 = time.perf_counter()
        self.batch.step(ids, nstep=nstep)
        return time.perf_counter() - t0

    def close(self) -> None:
        """Nothing to release: the batch's threads end with the batch."""


class DataSimulations:
    """P simulations, one ``MjData`` each, on ``threads`` threads: Gymnasium's ``mj_step`` then
    ``mj_rnePostConstraint``, in place. ``qpos``, ``qvel`` and the ``fields`` are [P, ...] copies taken after
    every call; ``ctrl`` [P, nu] is read at every step."""

    def __init__(self, model: mujoco.MjModel, num_envs: int, threads: int, fields: tuple[str, ...]) -> None:
        self.model = model
        self.data = [mujoco.MjData(model) for _ in range(num_envs)]
        self._sims = np.arange(num_envs)
        names = ("qpos", "qvel", *fields)
        for name in names:
            setattr(self, name, np.zeros((num_envs, *getattr(self.data[0], name).shape)))
        self.ctrl = np.zeros((num_envs, model.nu))
        # (the array, the simulation's own field) pairs, views made once: they stay valid while the MjData lives
        self._copies = [[(getattr(self, name), getattr(d, name)) for name in names] for d in self.data]
        self._ctrl = [d.ctrl for d in self.data]
        self.threads = threads
        self._pool = ThreadPoolExecutor(threads) if threads > 1 else None

    def reset(self, ids: np.ndarray | None, qpos: np.ndarray, qvel: np.ndarray) -> None:
        """Gymnasium's reset of simulations ``ids`` (None: all): ``mj_resetData``, the state, ``mj_forward``."""
        m = self.model
        for sim, q, v in zip(self._sims[rows(ids)].tolist(), qpos, qvel, strict=True):
            d = self.data[sim]
            mujoco.mj_resetData(m, d)
            d.qpos[:], d.qvel[:] = q, v
            mujoco.mj_forward(m, d)
            self._copy_out(sim)

    def step(self, ids: np.ndarray | None, nstep: int) -> float:
        """``nstep`` calls to ``mj_step`` from ``ctrl``, then ``mj_rnePostConstraint``, per simulation; returns
        the seconds of the ``mj_step`` calls alone, as if spread evenly over the threads (a bound for any
        loop around them)."""
        sims = iter(self._sims[rows(ids)].tolist())
        if self._pool is None:
            return self._run(sims, nstep)
        # every thread takes the next simulation from the one iterator, so none waits while another has work
        return sum(self._pool.map(self._run, [sims] * self.threads, [nstep] * self.threads)) / self.threads

    def _run(self, sims: Iterator[int], nstep: int) -> float:
        m, clock, physics = self.model, time.perf_counter, 0.0
        for sim in sims:
            d = self.data[sim]
            self._ctrl[sim][:] = self.ctrl[sim]
            t0 = clock()
            mujoco.mj_step(m, d, nstep)
            physics += clock() - t0
            mujoco.mj_rnePostConstraint(m, d)
            self._copy_out(sim)
        return physics

    def _copy_out(self, sim: int) -> None:
        for out, field in self._copies[sim]:
            out[sim] = field

    def close(self) -> None:
        if self._pool is not None:
            self._pool.shutdown()


class MujocoBatchEnv(BatchEnv):
    """P simulations of one task on ``num_threads`` MuJoCo threads, as a TorchRL env of batch size [P]."""

    def __init__(self, env_id: str, num_envs: int, num_threads: int = 1, model: mujoco.MjModel | None = None) -> None:
        """``model``: the task's model, changed (e.g. :mod:`~spn_torchrl.envs.mujoco210`); None: from its XML."""
        task = batch_task(env_id)
        self.env_id = env_id
        self.task = task
        self.model = mujoco.MjModel.from_xml_path(expand_model_path(task.xml)) if model is None else model
        m = self.model
        p = num_envs
        low = torch.as_tensor(m.actuator_ctrlrange[:, 0], dtype=torch.float32)
        high = torch.as_tensor(m.actuator_ctrlrange[:, 1], dtype=torch.float32)
        action_spec = Bounded(low.expand(p, m.nu), high.expand(p, m.nu), shape=(p, m.nu), dtype=torch.float32)
        super().__init__(num_envs, observation_size(m, task), action_spec, task.max_episode_steps)
        fields = STANDUP_FIELDS if task.standup else () if task.terms is None else task.terms.fields
        if POST_CONSTRAINT_FIELDS.intersection(fields):
            self.sims = DataSimulations(m, num_envs, num_threads, fields)
        else:
            self.sims = BatchSimulations(m, num_envs, num_threads, fields)
        self.dt = m.opt.timestep * task.frame_skip
        self._x_before = np.zeros(p)
        self.physics_seconds = 0.0  # the physics alone (benchmarks read it): see the simulations' step

    def _write_obs(self, ids: np.ndarray | None) -> None:
        """Gymnasium's ``_get_obs`` for the rows ``ids`` (None: all) into the observation buffer."""
        slots = rows(ids)
        m, task, sims = self.model, self.task, self.sims
        k = task.skipped_qpos
        parts = [sims.qpos[slots, k:], sims.qvel[slots]]
        if task.standup:
            parts += com_parts(m, sims, slots)
        if task.terms is not None:  # a task's own observation
            parts = task.terms.observe(m, sims, slots)
        if ids is None:
            np.concatenate(parts, axis=1, out=self._obs)
        else:
            self._obs[ids] = np.concatenate(parts, axis=1)

    def _reset_slots(self, ids: np.ndarray | None) -> None:
        states = [initial_state(self.task, self.model, self._rngs[sim]) for sim in self._all[rows(ids)]]
        qpos, qvel = zip(*states, strict=True)
        self.sims.reset(ids, np.stack(qpos), np.stack(qvel))
        self._write_obs(ids)

    def _advance(self, ids: np.ndarray | None, action: np.ndarray) -> None:
        slots = rows(ids)
        task, sims = self.task, self.sims
        sims.ctrl[slots] = action
        if task.terms is not None:
            self._x_before[slots] = task.terms.position(self.model, sims, slots)
        elif not task.standup:
            self._x_before[slots] = sims.qpos[slots, 0]
        self.physics_seconds += sims.step(ids, task.frame_skip)
        if task.terms is not None:  # the task's own reward; the loss of its healthy state ends the episode
            x_velocity = (task.terms.position(self.model, sims, slots) - self._x_before[slots]) / self.dt
            self._reward[slots], healthy = task.terms.reward(
                self.model, sims, slots, action, x_velocity, task.ctrl_cost_weight
            )
            self._terminated[slots] = ~healthy
        if task.standup:
            uph = sims.qpos[slots, 2] / self.model.opt.timestep
            quad_ctrl = task.ctrl_cost_weight * np.square(sims.ctrl[slots]).sum(-1)
            impact = np.minimum(
                IMPACT_COST_WEIGHT * np.square(sims.cfrc_ext[slots]).reshape(len(uph), -1).sum(-1), IMPACT_COST_MAX
            )
            self._reward[slots] = uph - quad_ctrl - impact + 1
        elif task.terms is None:
            # float32 action -> float32 control cost, as Gymnasium computes it on the action it is given
            ctrl_cost = task.ctrl_cost_weight * np.square(action).sum(-1)
            self._reward[slots] = (sims.qpos[slots, 0] - self._x_before[slots]) / self.dt - ctrl_cost
        self._write_obs(ids)

    def close(self, *, raise_if_closed: bool = True) -> None:
        self.sims.close()
        super().close(raise_if_closed=raise_if_closed)


def mujoco_batch_backend(env_id: str, num_envs: int, threads: int = 1) -> EnvBase:
    """Backend factory: ``threads`` physics threads."""
    return MujocoBatchEnv(env_id, num_envs, num_threads=threads)
