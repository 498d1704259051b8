"""``env.backend=gym_v2``: the paper's own simulator, Gym 0.21's MuJoCo v2 tasks on mujoco-py and MuJoCo 2.1.0.

That stack needs numpy<2 and an old pip, so it lives in a venv of its own (``bash scripts/make_gym_v2_env.sh``
creates it at ``.venv-gym-v2`` in the repository root, or where ``$SPN_GYM_V2_VENV`` says). A
:class:`GymV2Env` of P slots runs ``threads`` worker processes of that venv's python
(:mod:`~spn_torchrl.envs.gym_v2_server`), each holding a contiguous share of the slots, and talks to them over
pipes: a step sends each worker its slots' actions, then reads every worker's answer, so the workers step in
parallel. Episode seeds reach Gym 0.21 as it seeds an episode: ``env.seed(s)`` then ``env.reset()``; a reset
without a new seed goes on with the copy's generator. Slots, masks and the 1000-step time limit are
:class:`~spn_torchrl.envs.batch.BatchEnv`'s.
"""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from torchrl.data import Bounded

from spn_torchrl.envs.batch import BatchEnv, rows
from spn_torchrl.errors import ConfigError, SpnError

VENV_VARIABLE = "SPN_GYM_V2_VENV"
MAKE_COMMAND = "bash scripts/make_gym_v2_env.sh"
DEFAULT_VENV = Path(__file__).resolve().parents[2] / ".venv-gym-v2"
SERVER = Path(__file__).with_name("gym_v2_server.py")
CLOSE_TIMEOUT_S = 10.0


@dataclass(frozen=True)
class V2Task:
    """What Gym 0.21 says of a v2 task (checked against the worker's own report when an env starts)."""

    n_obs: int
    n_act: int
    action_bound: float  # the actuators' ctrlrange is [-bound, bound]
    max_episode_steps: int = 1000


V2_TASKS: dict[str, V2Task] = {
    "HalfCheetah-v2": V2Task(17, 6, 1.0),
    "Swimmer-v2": V2Task(8, 2, 1.0),
    "HumanoidStandup-v2": V2Task(376, 17, 0.4),
}


def v2_venv() -> Path:
    """The gym_v2 venv: ``$SPN_GYM_V2_VENV``, else ``.venv-gym-v2`` in the repository root."""
    return Path(os.environ.get(VENV_VARIABLE) or DEFAULT_VENV)


def v2_python() -> Path:
    """The gym_v2 venv's python; ConfigError naming the command that creates it when it is missing."""
    python = v2_venv() / "bin" / "python"
    if not python.is_file():
        raise ConfigError(
            f"env.backend=gym_v2 needs the Gym 0.21 + mujoco-py venv at {v2_venv()}, which does not exist: "
            f"create it with `{MAKE_COMMAND}` (or set {VENV_VARIABLE} to where it is)"
        )
    return python


def check_gym_v2(env_id: str) -> None:
    """ConfigError unless the gym_v2 venv exists (before any env is built)."""
    v2_python()


class Worker:
    """One server process holding ``count`` copies of a task."""

    def __init__(self, python: Path, env_id: str, count: int) -> None:
        self.count = count
        self.log = tempfile.TemporaryFile()  # the worker's stderr, shown when it fails
        self.proc = subprocess.Popen(
            [str(python), str(SERVER), env_id, str(count)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
        )
        self.info: dict = {}

    def start(self) -> dict:
        """The worker's report of its task and versions (its first line)."""
        line = self.proc.stdout.readline()
        if not line:
            raise self.failure("did not start")
        self.info = json.loads(line)
        return self.info

    def send(self, op: bytes, slots: np.ndarray, payload: bytes) -> None:
        try:
            self.proc.stdin.write(op + np.int32(len(slots)).tobytes() + slots.astype("<i4").tobytes() + payload)
            self.proc.stdin.flush()
        except (BrokenPipeError, OSError):
            raise self.failure("stopped") from None

    def receive(self, size: int) -> bytes:
        data = self.proc.stdout.read(size)
        if data is None or len(data) != size:
            raise self.failure("stopped")
        return data

    def failure(self, what: str) -> SpnError:
        """An error saying the worker ``what`` (did not start / stopped), with the end of its stderr."""
        self.proc.poll()
        self.log.seek(0)
        tail = self.log.read().decode(errors="replace").strip().splitlines()[-5:]
        return SpnError(
            f"env.backend=gym_v2: a worker ({v2_python()}) {what} (exit code {self.proc.returncode}): "
            + (" | ".join(tail) or "no output")
        )

    def close(self) -> None:
        if self.proc.poll() is None:
            try:
                self.proc.stdin.write(b"Q")
                self.proc.stdin.close()
            except (BrokenPipeError, OSError):
                pass
            try:
                self.proc.wait(CLOSE_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        self.proc.stdout.close()
        self.log.close()


class GymV2Env(BatchEnv):
    """P copies of a Gym 0.21 v2 task in ``workers`` server processes, as a TorchRL env of batch size [P]."""

    def __init__(self, env_id: str, num_envs: int, workers: int = 1) -> None:
        if env_id not in V2_TASKS:
            raise ConfigError(f"env.backend=gym_v2 steps {', '.join(V2_TASKS)}, not env.id={env_id!r}")
        task = V2_TASKS[env_id]
        p = num_envs
        bound = torch.full((p, task.n_act), task.action_bound)
        super().__init__(p, task.n_obs, Bounded(-bound, bound, shape=(p, task.n_act)), task.max_episode_steps)
        self.env_id = env_id
        self.n_act = task.n_act
        python = v2_python()
        workers = max(1, min(workers, p))
        self._share = -(-p // workers)  # slots per worker (the last may hold fewer)
        counts = [min(self._share, p - i * self._share) for i in range(workers)]
        self._workers = [Worker(python, env_id, c) for c in counts if c > 0]
        try:
            for worker in self._workers:
                info = worker.start()
                if (info["n_obs"], info["n_act"]) != (task.n_obs, task.n_act):
                    raise SpnError(
                        f"env.backend=gym_v2: {env_id} has n_obs={info['n_obs']}, n_act={info['n_act']} in "
                        f"{v2_venv()}, expected {task.n_obs}, {task.n_act}"
                    )
        except BaseException:
            self._close_workers()
            raise
        self.versions = {k: v for k, v in self._workers[0].info.items() if k not in ("action_low", "action_high")}
        self._seeds = np.full(p, -1, dtype=np.int64)  # the seed of each slot's next reset (-1: none)

    def _seed_slots(self, seeds) -> None:
        if len(seeds) != len(self._all):
            raise ValueError(f"expected {len(self._all)} seeds, one per slot, got {len(seeds)}")
        seeds = np.asarray(seeds, dtype=np.int64)
        if (seeds < 0).any():
            raise ValueError(f"env.backend=gym_v2 seeds episodes with env.seed(s): s must be >= 0, got {seeds.min()}")
        self._seeds = seeds.copy()

    def _groups(self, slots: np.ndarray) -> list[tuple[Worker, np.ndarray, np.ndarray]]:
        """(worker, positions in ``slots``, the worker's own slot numbers) for every worker with a slot."""
        owner = slots // self._share
        out = []
        for w in np.unique(owner).tolist():
            at = np.flatnonzero(owner == w)
            out.append((self._workers[w], at, slots[at] - w * self._share))
        return out

    def _reset_slots(self, ids: np.ndarray | None) -> None:
        slots = self._all[rows(ids)]
        groups = self._groups(slots)
        for worker, at, local in groups:
            worker.send(b"R", local, self._seeds[slots[at]].astype("<i8").tobytes())
        self._seeds[slots] = -1
        n = self._obs.shape[1]
        for worker, at, _ in groups:
            self._obs[slots[at]] = np.frombuffer(worker.receive(8 * n * len(at)), "<f8").reshape(len(at), n)

    def set_state(self, qpos: np.ndarray, qvel: np.ndarray) -> torch.Tensor:
        """Put every slot in the state ``qpos`` [P, nq], ``qvel`` [P, nv] (Gym's ``set_state``), e.g. to start
        another simulator from the same one; returns the observations [P, n_obs], float64. The slots' step
        counters restart."""
        states = np.concatenate([qpos, qvel], axis=1).astype("<f8")
        groups = self._groups(self._all)
        for worker, at, local in groups:
            worker.send(b"X", local, states[at].tobytes())
        n = self._obs.shape[1]
        for worker, at, _ in groups:
            self._obs[at] = np.frombuffer(worker.receive(8 * n * len(at)), "<f8").reshape(len(at), n)
        self._elapsed[:] = 0
        self._terminated[:] = False
        return torch.from_numpy(self._obs.copy())

    def _advance(self, ids: np.ndarray | None, action: np.ndarray) -> None:
        slots = self._all[rows(ids)]
        action = np.ascontiguousarray(action, dtype="<f4").reshape(len(slots), self.n_act)
        groups = self._groups(slots)
        for worker, at, local in groups:
            worker.send(b"S", local, action[at].tobytes())
        n = self._obs.shape[1]
        for worker, at, _ in groups:
            k = len(at)
            data = worker.receive(8 * n * k + 8 * k + k)
            self._obs[slots[at]] = np.frombuffer(data, "<f8", n * k).reshape(k, n)
            self._reward[slots[at]] = np.frombuffer(data, "<f8", k, 8 * n * k)
            self._terminated[slots[at]] = np.frombuffer(data, np.uint8, k, 8 * n * k + 8 * k).astype(bool)

    def _close_workers(self) -> None:
        for worker in self._workers:
            worker.close()
        self._workers = []

    def close(self, *, raise_if_closed: bool = True) -> None:
        self._close_workers()
        super().close(raise_if_closed=raise_if_closed)


def gym_v2_backend(env_id: str, num_envs: int, threads: int = 1) -> GymV2Env:
    """Backend factory: ``threads`` worker processes of the gym_v2 venv."""
    return GymV2Env(env_id, num_envs, workers=threads)
