"""The GA's population as N MuJoCo Warp worlds on one device (a GPU): Gymnasium v5 HalfCheetah, Swimmer and
HumanoidStandup with observations, rewards and done flags as torch tensors on that device.

Replicates what :mod:`spn_torchrl.envs.mujoco` replicates (observation, every reward term, the reset distribution
and per-slot seeding, frame skip, the 1000-step time limit), in MuJoCo Warp's float32 instead of MuJoCo's float64,
so trajectories agree with Gymnasium's to float32 rounding, which the tasks' chaos then amplifies
(``tests/test_mujoco_warp.py``). HumanoidStandup's XML asks for the PGS solver, which Warp lacks: the Warp model
uses Newton instead. Slot i's world is world i; a reset draws its state on the host from the slot's generator
(``reset(seed=s)`` of the Gymnasium task) and copies it to the device. On a CUDA device the frame-skip substeps
(and HumanoidStandup's ``rne_postconstraint``) run as one captured CUDA graph. Needs the ``gpu`` extra.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

import mujoco
import numpy as np
import torch
from gymnasium.envs.mujoco.mujoco_env import expand_model_path
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Bounded, Categorical, Composite, Unbounded
from torchrl.envs import EnvBase

from spn_torchrl.envs.batch import rows, selected_slots, slot_generator, step_output
from spn_torchrl.envs.mujoco import (
    IMPACT_COST_MAX,
    IMPACT_COST_WEIGHT,
    batch_task,
    initial_state,
    observation_size,
)
from spn_torchrl.errors import ConfigError, require


@dataclass(frozen=True)
class WarpSizes:
    """Per-world capacities of a task's Warp data: contacts and constraint rows, at least 3 times MuJoCo C's most
    in 1000-step random-control episodes (HalfCheetah 4 and 17, Swimmer 0 and 2, HumanoidStandup 11 and 38);
    :meth:`MujocoWarpEnv.check_overflow` catches an episode that needed more."""

    nconmax: int
    njmax: int


WARP_SIZES: dict[str, WarpSizes] = {
    "HalfCheetah-v5": WarpSizes(nconmax=24, njmax=128),
    "Swimmer-v5": WarpSizes(nconmax=8, njmax=16),
    "HumanoidStandup-v5": WarpSizes(nconmax=64, njmax=128),
}


def torch_device(device: str) -> torch.device:
    """The torch device ``env.device`` names: ``cpu``, or ``cuda``/``cuda:<index>`` of a visible CUDA device;
    ConfigError for anything else."""
    try:
        dev = torch.device(device)
    except (RuntimeError, TypeError):
        raise ConfigError(f"env.device must be cpu, cuda or cuda:<index>, got {device!r}") from None
    if dev.type == "cpu":
        return dev
    if dev.type != "cuda":
        raise ConfigError(f"env.device must be cpu, cuda or cuda:<index>, got {device!r}")
    if not torch.cuda.is_available():
        raise ConfigError(f"env.device={device}: this machine has no CUDA device visible to torch; use env.device=cpu")
    count = torch.cuda.device_count()
    index = torch.cuda.current_device() if dev.index is None else dev.index
    if not 0 <= index < count:
        raise ConfigError(f"env.device={device}: CUDA device index must be in [0, {count - 1}]")
    return torch.device("cuda", index)


def warp_model(env_id: str) -> mujoco.MjModel:
    """The MuJoCo model of a task as the Warp backend simulates it: Gymnasium's XML, with the Newton solver
    in place of PGS (which MuJoCo Warp does not implement; HumanoidStandup asks for PGS)."""
    model = mujoco.MjModel.from_xml_path(expand_model_path(batch_task(env_id, "mujoco_warp").xml))
    if model.opt.solver == mujoco.mjtSolver.mjSOL_PGS:
        model.opt.solver = mujoco.mjtSolver.mjSOL_NEWTON
    return model


class MujocoWarpEnv(EnvBase):
    """P worlds of one task on ``device``, as a TorchRL env of batch size [P]; every tensor stays there.

    :meth:`step_slots_torch` is the step without TensorDicts (what the evaluator calls); TorchRL's ``step``
    honours the ``"_step"`` mask and ``reset`` the ``"_reset"`` mask and ``seed=[...]`` (a seed per slot), as
    :class:`~spn_torchrl.envs.batch.BatchEnv` does. Idle slots keep their state and observation and get a
    zero reward (the device still simulates them: a GPU steps every world at once).
    """

    def __init__(self, env_id: str, num_envs: int, device: str = "cpu") -> None:
        task = batch_task(env_id, "mujoco_warp")
        if env_id not in WARP_SIZES:
            raise ConfigError(
                f"env.backend=mujoco_warp supports {', '.join(WARP_SIZES)}, not {env_id!r}: "
                "use env.backend=mujoco_batch or gymnasium for it"
            )
        dev = torch_device(device)
        wp = require("warp", "gpu")
        mjw = require("mujoco_warp", "gpu")
        wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)  # no line per kernel module (hundreds)
        wp.init()
        super().__init__(batch_size=torch.Size([num_envs]), device=dev)
        self.env_id, self.task = env_id, task
        self.model = warp_model(env_id)
        m, p = self.model, num_envs
        self.max_episode_steps = task.max_episode_steps
        self.dt = m.opt.timestep * task.frame_skip
        self._wp, self._mjw = wp, mjw
        self.wp_device = wp.device_from_torch(dev)
        sizes = WARP_SIZES[env_id]
        with wp.ScopedDevice(self.wp_device):
            self.wmodel = mjw.put_model(m)
            self.wdata = mjw.make_data(m, nworld=p, nconmax=sizes.nconmax, njmax=sizes.njmax)
        d = self.wdata
        self.qpos, self.qvel, self.ctrl = wp.to_torch(d.qpos), wp.to_torch(d.qvel), wp.to_torch(d.ctrl)
        # the state a step carries to the next: what an idle slot gets back after a step of every world
        self._state = [self.qpos, self.qvel, wp.to_torch(d.qacc_warmstart), wp.to_torch(d.time)]
        if m.na:
            self._state.append(wp.to_torch(d.act))
        self._saved = [torch.empty_like(x) for x in self._state]
        if task.standup:
            self.cinert, self.cvel = wp.to_torch(d.cinert), wp.to_torch(d.cvel)
            self.qfrc_actuator, self.cfrc_ext = wp.to_torch(d.qfrc_actuator), wp.to_torch(d.cfrc_ext)
        self._overflow = wp.to_torch(d.overflow)
        n_obs = observation_size(m, task)
        self._obs = torch.zeros(p, n_obs, device=dev)
        self._elapsed = torch.zeros(p, dtype=torch.int64, device=dev)
        self._x_before = torch.zeros(p, device=dev)
        self._rngs = [slot_generator(0) for _ in range(p)]
        self._all = np.arange(p)
        low = torch.as_tensor(m.actuator_ctrlrange[:, 0], dtype=torch.float32, device=dev)
        high = torch.as_tensor(m.actuator_ctrlrange[:, 1], dtype=torch.float32, device=dev)
        self.action_spec = Bounded(
            low.expand(p, m.nu), high.expand(p, m.nu), shape=(p, m.nu), dtype=torch.float32, device=dev
        )
        self.observation_spec = Composite(
            observation=Unbounded(shape=(p, n_obs), dtype=torch.float32, device=dev), shape=(p,), device=dev
        )
        self.reward_spec = Unbounded(shape=(p, 1), dtype=torch.float32, device=dev)
        self.done_spec = Composite(
            {
                key: Categorical(2, shape=(p, 1), dtype=torch.bool, device=dev)
                for key in ("done", "terminated", "truncated")
            },
            shape=(p,),
            device=dev,
        )
        self._graph = None
        with wp.ScopedDevice(self.wp_device):
            self._substeps()  # compiles (or loads) every kernel: a capture cannot
            mjw.reset_data(self.wmodel, d)
            if self.wp_device.is_cuda:
                self._stream = self.wp_device.stream
                self._torch_stream = wp.stream_from_torch(dev)
                self._events = (wp.Event(self.wp_device), wp.Event(self.wp_device))
                with wp.ScopedCapture(device=self.wp_device, stream=self._stream) as capture:
                    self._substeps()
                self._graph = capture.graph

    def _substeps(self) -> None:
        """One env step of every world: frame_skip physics steps, then Gymnasium's ``mj_rnePostConstraint``."""
        for _ in range(self.task.frame_skip):
            self._mjw.step(self.wmodel, self.wdata)
        if self.task.standup:
            self._mjw.rne_postconstraint(self.wmodel, self.wdata)

    def simulate(self) -> None:
        """Advance every world by one env step with the controls in place, and nothing else (no reward, no
        observation): what a benchmark of the physics alone times. Asynchronous on a CUDA device."""
        with self._after_torch():
            if self._graph is None:
                self._substeps()
            else:
                self._wp.capture_launch(self._graph, stream=self._stream)

    @contextlib.contextmanager
    def _after_torch(self) -> Iterator[None]:
        """Warp's launches in the block run on this device after the torch work queued so far (e.g. controls
        written through the zero-copy views), and later torch work after them; on a CUDA device, by events
        between Warp's stream and torch's, with no host synchronisation."""
        with self._wp.ScopedDevice(self.wp_device):
            if self._graph is not None:
                self._stream.wait_stream(self._torch_stream, self._events[0])
            yield
            if self._graph is not None:
                self._torch_stream.wait_stream(self._stream, self._events[1])

    def _observation(self) -> torch.Tensor:
        """Gymnasium's ``_get_obs`` of every world, float32 [P, n] (a new tensor)."""
        p, task = self.batch_size[0], self.task
        parts = [self.qpos[:, task.skipped_qpos :], self.qvel]
        if task.standup:
            parts += [
                self.cinert[:, 1:].reshape(p, -1),
                self.cvel[:, 1:].reshape(p, -1),
                self.qfrc_actuator[:, 6:],
                self.cfrc_ext[:, 1:].reshape(p, -1),
            ]
        return torch.cat(parts, dim=1)

    def step_slots_torch(
        self, action: torch.Tensor, active: torch.Tensor | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Step the ``active`` slots ([P] bool on the device; None: all) with ``action`` ([c, m], a row for
        each of the first c <= P slots; later slots get zero controls). Returns every slot's observation
        [P, n] float32, reward [P] float32 (0 for idle slots), terminated and truncated [P] bool, new tensors
        on the device; no host synchronisation."""
        p, task = self.batch_size[0], self.task
        c = action.shape[0]
        if not 0 < c <= p or action.shape[1:] != self.ctrl.shape[1:]:
            raise ValueError(f"action must be [c, {self.ctrl.shape[1]}] with 0 < c <= {p}, got {tuple(action.shape)}")
        self.ctrl[:c] = action
        if c < p:
            self.ctrl[c:] = 0.0
        if not task.standup:
            self._x_before.copy_(self.qpos[:, 0])
        if active is not None:
            for saved, live in zip(self._saved, self._state):
                saved.copy_(live)
        self.simulate()
        if task.standup:
            uph = self.qpos[:, 2] / self.model.opt.timestep
            quad_ctrl = task.ctrl_cost_weight * self.ctrl.square().sum(-1)
            impact = torch.clamp(IMPACT_COST_WEIGHT * self.cfrc_ext.square().sum((1, 2)), max=IMPACT_COST_MAX)
            reward = uph - quad_ctrl - impact + 1
        else:
            reward = (self.qpos[:, 0] - self._x_before) / self.dt - task.ctrl_cost_weight * self.ctrl.square().sum(-1)
        obs = self._observation()
        if active is None:
            self._elapsed += 1
        else:
            for saved, live in zip(self._saved, self._state):  # idle worlds return to their state
                keep = active.view(-1, *([1] * (live.dim() - 1)))
                live.copy_(torch.where(keep, live, saved))
            obs = torch.where(active[:, None], obs, self._obs)
            reward = torch.where(active, reward, 0.0)
            self._elapsed += active
        self._obs = obs
        terminated = torch.zeros(p, dtype=torch.bool, device=self.device)  # these tasks never terminate
        return obs, reward, terminated, self._elapsed >= self.max_episode_steps  # as TimeLimit

    def check_overflow(self, count: int | None = None) -> None:
        """RuntimeError if a world among the first ``count`` (None: all) ran out of contact or constraint
        capacity since its reset (Warp then drops contacts: a different episode). One host read."""
        flags = self._overflow[:count]
        if bool(flags.any()):
            worlds = torch.nonzero(flags).flatten().tolist()
            raise RuntimeError(
                f"{self.env_id}: MuJoCo Warp overflowed its per-world capacity ({WARP_SIZES[self.env_id]}) in "
                f"worlds {worlds[:5]}{'...' if len(worlds) > 5 else ''} (flags {int(flags.max())}): raise WARP_SIZES"
            )

    def _seed_slots(self, seeds) -> None:
        if len(seeds) != len(self._all):
            raise ValueError(f"expected {len(self._all)} seeds, one per slot, got {len(seeds)}")
        self._rngs = [slot_generator(s) for s in seeds]

    def _set_seed(self, seed: int | None) -> None:
        """Seed slot i with ``seed + i`` and reset, as :class:`~spn_torchrl.envs.batch.BatchEnv` does."""
        if seed is not None:
            self._seed_slots(seed + self._all)
            self._restart(None)

    def _restart(self, ids: np.ndarray | None) -> None:
        """Reset worlds ``ids`` (None: all) to a state drawn from their generators, as Gymnasium's reset
        (``mj_resetData``, the noisy qpos and qvel, ``mj_forward``)."""
        mjw, dev = self._mjw, self.device
        slots = self._all[rows(ids)]
        states = [initial_state(self.task, self.model, self._rngs[s]) for s in slots]
        index = torch.as_tensor(slots, device=dev)
        mask = torch.zeros(len(self._all), dtype=torch.bool, device=dev)
        mask[index] = True
        with self._after_torch():
            mjw.reset_data(self.wmodel, self.wdata, reset=self._wp.from_torch(mask))
        self.qpos[index] = torch.as_tensor(np.stack([q for q, _ in states]), dtype=torch.float32, device=dev)
        self.qvel[index] = torch.as_tensor(np.stack([v for _, v in states]), dtype=torch.float32, device=dev)
        with self._after_torch():  # every world's derived fields from its state; the others' next step redoes them
            mjw.forward(self.wmodel, self.wdata)
        if self.task.standup:
            self.cfrc_ext[index] = 0.0  # mj_resetData clears it and mj_forward does not compute it
        self._obs = torch.where(mask[:, None], self._observation(), self._obs)
        self._elapsed[index] = 0

    def _reset(self, tensordict: TensorDictBase | None = None, seed=None, **kwargs) -> TensorDictBase:
        """Reset the slots of the ``"_reset"`` mask (all without one); ``seed`` (a seed per slot) first seeds
        every slot, as ``reset(seed=[...])`` of a Gymnasium vector env does."""
        if seed is not None:
            self._seed_slots(seed)
        ids = selected_slots(None if tensordict is None else tensordict.get("_reset", None))
        if ids is None or len(ids):
            self._restart(ids)
        false = torch.zeros(*self.batch_size, 1, dtype=torch.bool, device=self.device)
        return TensorDict(
            {"observation": self._obs.clone(), "done": false, "terminated": false.clone(), "truncated": false.clone()},
            batch_size=self.batch_size,
            device=self.device,
        )

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        mask = tensordict.get("_step", None)
        active = None if mask is None else mask.reshape(-1).to(self.device)
        return step_output(*self.step_slots_torch(tensordict.get("action"), active), self.batch_size, self.device)


def mujoco_warp_backend(env_id: str, num_envs: int, threads: int = 1, device: str = "cpu") -> EnvBase:
    """Backend factory: ``num_envs`` MuJoCo Warp worlds on ``device`` (``env.device``); one device runs every
    world, so ``threads`` (physics threads elsewhere) must be 1."""
    if threads != 1:
        raise ConfigError(
            f"env.backend=mujoco_warp runs every world on env.device: env.threads must be 1, got {threads}"
        )
    return MujocoWarpEnv(env_id, num_envs, device)
