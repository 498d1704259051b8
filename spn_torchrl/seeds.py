"""Every seed a run derives from its own: fixed weights and GA draws come from the run seed's generator; the env
seed of each episode comes from (run seed, generation or iteration, role, index), so that a resumed, extended or
differently sharded run gives every individual the same episode."""

from __future__ import annotations

import numpy as np

# roles of a GA generation's episodes, and of a PPO iteration's
FITNESS, REEVALUATION = 0, 1
COLLECTION, EVALUATION = 0, 1


def episode_seed(run_seed: int, step: int, role: int) -> int:
    """The base env seed of one role's episodes in a generation or iteration (``step``)."""
    return int(np.random.SeedSequence([run_seed, step, role]).generate_state(1)[0] >> 1)


def episode_seeds(run_seed: int, step: int, role: int, count: int) -> np.ndarray:
    """Env seeds [count] of individuals 0..count-1 of one role: ``episode_seed + index``, whatever rollout or
    shard an individual runs in."""
    return episode_seed(run_seed, step, role) + np.arange(count, dtype=np.int64)


def slot_seeds(seeds: int | np.ndarray, count: int) -> np.ndarray:
    """Seeds [count] of ``count`` env slots: an int ``s`` seeds slot i with ``s + i`` (as TorchRL's
    ``set_seed`` of a vector env); an array gives each slot its own."""
    if np.ndim(seeds) == 0:
        return int(seeds) + np.arange(count, dtype=np.int64)
    seeds = np.asarray(seeds, dtype=np.int64)
    if seeds.shape != (count,):
        raise ValueError(f"expected {count} seeds, one per genome, got shape {seeds.shape}")
    return seeds
