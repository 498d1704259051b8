"""Population rollouts: genomes -> episode return, env steps and hidden spike counts per individual."""

from __future__ import annotations

import copy
import logging
from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch
from tensordict import TensorDictBase
from torchrl.envs import EnvBase

from spn_torchrl.envs.batch import BatchEnv
from spn_torchrl.envs.mujoco_warp import MujocoWarpEnv
from spn_torchrl.seeds import slot_seeds
from spn_torchrl.snn.observations import Norm
from spn_torchrl.snn.policies import PopulationSPN

log = logging.getLogger("spn_torchrl")


@dataclass
class Episodes:
    """One episode per individual: undiscounted return, env steps and total hidden spikes; with normalised
    observations also the moments of the observations each policy saw (count [B], sum and sum of squares
    [B, n], float64), from which the running statistics are updated."""

    returns: torch.Tensor
    steps: torch.Tensor
    spikes: torch.Tensor
    obs_count: torch.Tensor | None = None
    obs_sum: torch.Tensor | None = None
    obs_squares: torch.Tensor | None = None

    @property
    def total_steps(self) -> int:
        return int(self.steps.sum())

    def part(self, start: int, stop: int) -> Episodes:
        """The episodes of individuals ``start`` to ``stop - 1``."""
        fields = (self.returns, self.steps, self.spikes, self.obs_count, self.obs_sum, self.obs_squares)
        return Episodes(*(None if f is None else f[start:stop] for f in fields))

    @property
    def moments(self) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """The observation moments per individual (count, sum, sum of squares)."""
        if self.obs_count is None:
            raise ValueError("these episodes were run without observation normalisation: no moments")
        return self.obs_count, self.obs_sum, self.obs_squares


def spike_rate(spikes: torch.Tensor, steps: torch.Tensor, hidden: int, time_steps: int) -> float:
    """Hidden spikes per neuron per simulation step over episodes (the rate the energy model uses)."""
    return float(spikes.sum() / (steps.sum() * hidden * time_steps))


class PopulationEvaluator:
    """Runs a genome set on one batched env: every member to its own episode end, then frozen.

    The env (batch [P]) is built once and reused; it needs no transforms, as returns and steps are counted
    here. Slot i is reset with ``seeds[i]`` (:func:`~spn_torchrl.seeds.slot_seeds`), so an individual's
    episode depends on its seed only. A call with fewer than P genomes leaves the remaining slots out of
    every result. A batch backend (:class:`~spn_torchrl.envs.batch.BatchEnv`) is stepped
    through :meth:`~spn_torchrl.envs.batch.BatchEnv.step_slots`, the core of its TorchRL ``step`` without the
    TensorDicts, on the slots still running; any other env through TorchRL's ``step_and_maybe_reset``, with the
    ``"_step"`` mask once some slots are idle. A device env (:class:`~spn_torchrl.envs.mujoco_warp.MujocoWarpEnv`)
    runs with a copy of the SPN on its device, and the loop keeps its sums and masks there
    (:meth:`_run_on_device`); the episodes come back on the CPU.
    """

    STOP_CHECK_EVERY = 10  # device loop: env steps between the host reads that stop it once every slot is done

    def __init__(self, env: EnvBase, spn: PopulationSPN, max_episode_steps: int) -> None:
        self.env = env
        self.on_device = isinstance(env, MujocoWarpEnv)
        if self.on_device and spn.w1.device != env.device:
            spn = copy.deepcopy(spn).to(env.device)  # the caller's SPN stays where it is
        self.spn = spn
        self.shape = env.batch_size
        self.size = env.batch_size.numel()
        self.max_episode_steps = max_episode_steps
        self.direct = isinstance(env, BatchEnv)
        if len(self.shape) != 1:
            raise ValueError(f"the evaluator steps an env of batch [P], got {tuple(self.shape)}")
        self._td: TensorDictBase | None = None

    def __call__(
        self, genomes: torch.Tensor, seeds: int | np.ndarray, norm: Norm | None = None, runs: np.ndarray | None = None
    ) -> Episodes:
        """One episode per genome, slot i reset with ``seeds[i]``; ``norm``: each genome's observation
        normalisation ([B, n] or [1, n]), whose episodes then also return the moments of what each policy saw;
        ``runs`` [B]: each genome's run where the SPN holds several runs' fixed weights
        (:class:`~spn_torchrl.snn.policies.PopulationSPN`)."""
        count = genomes.shape[0]
        if not 0 < count <= self.size:
            raise ValueError(f"the env holds {self.size} individuals, got {count} genomes")
        idle = np.zeros(self.size - count, dtype=np.int64)  # any seed: idle slots are never counted
        seeds = np.concatenate([slot_seeds(seeds, count), idle])
        self.spn.set_genomes(genomes, None if runs is None else torch.from_numpy(np.asarray(runs, dtype=np.int64)))
        self.spn.set_observation_norm(norm)
        if self.on_device:
            if norm is not None:
                raise ValueError("the device loop does not gather observation statistics")
            return self._run_on_device(count, seeds)
        active = torch.arange(self.size) < count
        returns = torch.zeros(self.size)
        steps = torch.full((self.size,), self.max_episode_steps)  # until a slot's episode ends earlier
        spikes = torch.zeros(count)
        everyone = count == self.size  # while every slot runs, nothing needs masking
        seen = None if norm is None else ObservedMoments(count)

        self._td = self.env.reset(seed=seeds.tolist())
        obs = self._td.get("observation").reshape(self.size, -1)
        for step in range(1, self.max_episode_steps + 1):
            if seen is not None:
                seen.add(obs[:count], None if everyone else active[:count])
            # the SPN called directly: a TensorDictModule wrapper costs more per step than the SNN
            action, hidden_spikes = self.spn(obs[:count])
            spikes += hidden_spikes if everyone else hidden_spikes * active[:count]
            obs, reward, done = self._step(action, None if everyone else active)
            returns += reward if everyone else reward * active  # float32 sums in step order, as TorchRL's RewardSum
            finished = done if everyone else done & active
            if finished.any():
                steps[finished] = step
                active &= ~finished
                everyone = False
                if not active.any():
                    break
        self._td = None
        episodes = Episodes(returns[:count], steps[:count], spikes)
        if seen is not None:
            episodes.obs_count, episodes.obs_sum, episodes.obs_squares = seen.count, seen.sum, seen.squares
        return episodes

    def _run_on_device(self, count: int, seeds: np.ndarray) -> Episodes:
        """The episode loop on the env's device: the same sums in the same order as the CPU loop, with no
        host round trip per step; every :attr:`STOP_CHECK_EVERY` steps one read of the active mask stops the
        loop once every slot is done (the extra steps of finished slots are never counted)."""
        env, dev = self.env, self.env.device
        active = torch.arange(self.size, device=dev) < count
        returns = torch.zeros(self.size, device=dev)
        steps = torch.full((self.size,), self.max_episode_steps, device=dev)
        spikes = torch.zeros(count, device=dev)
        obs = env.reset(seed=seeds.tolist()).get("observation")
        for step in range(1, self.max_episode_steps + 1):
            action, hidden_spikes = self.spn(obs[:count])
            spikes += hidden_spikes * active[:count]
            obs, reward, terminated, truncated = env.step_slots_torch(action, active)
            returns += reward * active  # float32 sums in step order, as the CPU loop
            finished = (terminated | truncated) & active
            steps.masked_fill_(finished, step)
            active &= ~finished
            if step % self.STOP_CHECK_EVERY == 0 and not bool(active.any()):
                break
        env.check_overflow(count)
        return Episodes(returns[:count].cpu(), steps[:count].cpu(), spikes.cpu())

    def _step(
        self, action: torch.Tensor, active: torch.Tensor | None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        """Step the ``active`` slots (None: all) with ``action`` (a row for each of the first slots); the
        observations [P, n], rewards [P] and done flags [P] of every slot."""
        if self.direct:
            ids = None if active is None else np.flatnonzero(active.numpy())
            rows = action.numpy()
            obs, reward, terminated, truncated = self.env.step_slots(rows if ids is None else rows[ids], ids)
            return obs, reward, terminated | truncated
        idle = self.size - action.shape[0]
        if idle:  # the idle slots repeat the first action, a valid one that is never counted
            action = torch.cat([action, action[:1].expand(idle, *action.shape[1:])])
        td = self._td
        td.set("action", action.reshape(*self.shape, *action.shape[1:]))
        if active is not None:
            td.set("_step", active.clone())
        stepped, self._td = self.env.step_and_maybe_reset(td)
        nxt = stepped.get("next")
        obs = self._td.get("observation").reshape(self.size, -1)
        return obs, nxt.get("reward").reshape(self.size).float(), nxt.get("done").reshape(self.size)

    def close(self) -> None:
        if not self.env.is_closed:
            self.env.close()


class ObservedMoments:
    """Per env slot, the count, sum and sum of squares (float64) of the observations its policy saw."""

    def __init__(self, count: int) -> None:
        self.count = torch.zeros(count, dtype=torch.int64)
        self.sum: torch.Tensor | None = None
        self.squares: torch.Tensor | None = None

    def add(self, obs: torch.Tensor, active: torch.Tensor | None) -> None:
        """One step's observations [B, n] of the ``active`` slots (None: all)."""
        x = torch.as_tensor(obs).to(torch.float64)
        if self.sum is None:
            self.sum, self.squares = torch.zeros_like(x), torch.zeros_like(x)
        if active is not None:
            x = torch.where(active[:, None], x, 0.0)
        self.count += 1 if active is None else active.to(torch.int64)
        self.sum += x
        self.squares += x * x


class Evaluator(Protocol):
    """What the GA loop needs: genomes [B, D] and their env seeds [B] in (with normalised observations, each
    genome's normalisation; for an SPN that holds several runs' fixed weights, each genome's run), one episode
    per genome out."""

    def __call__(
        self, genomes: torch.Tensor, seeds: np.ndarray, norm: Norm | None = None, runs: np.ndarray | None = None
    ) -> Episodes: ...

    def close(self) -> None: ...
