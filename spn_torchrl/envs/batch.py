"""The common part of the batched TorchRL envs that replicate a Gymnasium task in one process.

P slots, each with its own seeded generator (a slot seeded with s draws what ``gym.make(id).reset(seed=s)`` draws;
``set_seed(s)`` seeds slot i with s + i, as TorchRL's GymWrapper seeds a vector env; ``reset(seed=[...])`` one seed a slot), TorchRL's ``"_step"`` and ``"_reset"`` masks (idle slots
cost nothing), an elapsed-step counter with the task's time limit (truncation), and the TensorDict plumbing.
A subclass simulates: :meth:`_reset_slots` and :meth:`_advance`.
"""

from __future__ import annotations

import numpy as np
import torch
from tensordict import TensorDict, TensorDictBase
from torchrl.data import Categorical, Composite, TensorSpec, Unbounded
from torchrl.envs import EnvBase


class BatchEnv(EnvBase):
    """P copies of a task stepped together; observations float32 [P, n], rewards [P, 1]."""

    def __init__(self, num_envs: int, n_obs: int, action_spec: TensorSpec, max_episode_steps: int) -> None:
        super().__init__(batch_size=torch.Size([num_envs]))
        p = num_envs
        self.max_episode_steps = max_episode_steps
        self._obs = np.zeros((p, n_obs))
        self._reward = np.zeros(p)
        self._terminated = np.zeros(p, dtype=bool)
        self._elapsed = np.zeros(p, dtype=np.int64)
        self._rngs = [np.random.Generator(np.random.PCG64()) for _ in range(p)]
        self._all = np.arange(p)
        self.action_spec = action_spec
        self.observation_spec = Composite(observation=Unbounded(shape=(p, n_obs), dtype=torch.float32), shape=(p,))
        self.reward_spec = Unbounded(shape=(p, 1), dtype=torch.float32)
        self.done_spec = Composite(
            {key: Categorical(2, shape=(p, 1), dtype=torch.bool) for key in ("done", "terminated", "truncated")},
            shape=(p,),
        )
        self._false = torch.zeros(p, 1, dtype=torch.bool)

    def _reset_slots(self, ids: np.ndarray | None) -> None:
        """Draw the initial state of slots ``ids`` (None: all) from their generators and write their
        observations into ``self._obs``."""
        raise NotImplementedError

    def _advance(self, ids: np.ndarray | None, action: np.ndarray) -> None:
        """Step slots ``ids`` (None: all) with their actions (rows of ``action`` for those slots only) and
        write their observations, rewards and terminations into ``self._obs``, ``self._reward`` and
        ``self._terminated``."""
        raise NotImplementedError

    def _set_seed(self, seed: int | None) -> None:
        """Seed slot i with ``seed + i`` and reset, as TorchRL's GymWrapper does on a vector env."""
        if seed is not None:
            self._seed_slots(seed + self._all)
            self._restart(None)

    def _seed_slots(self, seeds) -> None:
        """Give slot i the generator that ``reset(seed=seeds[i])`` of the Gymnasium task makes."""
        if len(seeds) != len(self._all):
            raise ValueError(f"expected {len(self._all)} seeds, one per slot, got {len(seeds)}")
        self._rngs = [slot_generator(s) for s in seeds]

    def _restart(self, ids: np.ndarray | None) -> None:
        self._elapsed[rows(ids)] = 0
        self._terminated[rows(ids)] = False
        self._reset_slots(ids)

    def _reset(self, tensordict: TensorDictBase | None = None, seed=None, **kwargs) -> TensorDictBase:
        """Reset the slots of the ``"_reset"`` mask (all without one); ``seed`` (a seed per slot) first seeds
        every slot, as ``reset(seed=[...])`` of a Gymnasium vector env does."""
        if seed is not None:
            self._seed_slots(seed)
        ids = selected_slots(None if tensordict is None else tensordict.get("_reset", None))
        if ids is None or len(ids):
            self._restart(ids)
        return TensorDict(
            {
                "observation": torch.from_numpy(self._obs).float(),
                "done": self._false.clone(),
                "terminated": self._false.clone(),
                "truncated": self._false.clone(),
            },
            batch_size=self.batch_size,
        )

    def step_slots(
        self, action: np.ndarray, ids: np.ndarray | None = None
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
        """Step slots ``ids`` (None: all) with their actions (a row per stepped slot): what :meth:`_step` does
        without TensorDicts. Returns every slot's observation [P, n] float32, reward [P] float32 (0 for the
        slots left out), terminated and truncated [P] bool, each a new tensor."""
        if ids is not None:
            self._reward[:] = 0.0
        self._advance(ids, action)
        self._elapsed[rows(ids)] += 1
        return (
            torch.from_numpy(self._obs).float(),
            torch.from_numpy(self._reward).float(),
            torch.from_numpy(self._terminated.copy()),
            torch.from_numpy(self._elapsed >= self.max_episode_steps),  # as TimeLimit
        )

    def _step(self, tensordict: TensorDictBase) -> TensorDictBase:
        ids = selected_slots(tensordict.get("_step", None))
        action = tensordict.get("action").detach().numpy()
        return step_output(*self.step_slots(action[rows(ids)], ids), self.batch_size)


def step_output(
    obs: torch.Tensor,
    reward: torch.Tensor,
    terminated: torch.Tensor,
    truncated: torch.Tensor,
    batch_size: torch.Size,
    device: torch.device | None = None,
) -> TensorDict:
    """What a TorchRL ``_step`` returns for every slot's observation [P, n], reward [P] and flags [P]."""
    terminated, truncated = terminated.unsqueeze(-1), truncated.unsqueeze(-1)
    return TensorDict(
        {
            "observation": obs,
            "reward": reward.unsqueeze(-1),
            "done": terminated | truncated,
            "terminated": terminated,
            "truncated": truncated,
        },
        batch_size=batch_size,
        device=device,
    )


def slot_generator(seed: int) -> np.random.Generator:
    """The generator of a slot seeded with ``seed``: what ``reset(seed=seed)`` of a Gymnasium task makes."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed))))


def rows(ids: np.ndarray | None) -> slice | np.ndarray:
    """An index of the slots ``ids`` (None: all) into arrays with one row per slot."""
    return slice(None) if ids is None else ids


def selected_slots(mask: torch.Tensor | None) -> np.ndarray | None:
    """The slot indices a TorchRL ``_step``/``_reset`` mask (on any device) selects; None for all (or no mask)."""
    if mask is None:
        return None
    mask = mask.reshape(-1).cpu().numpy()
    return None if mask.all() else np.flatnonzero(mask)
