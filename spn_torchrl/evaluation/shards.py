"""A population cut into contiguous shards, each evaluated by a worker that holds its own batched env.

What the multi-process evaluators share (``evaluator.processes`` on this machine, ``evaluator=ray`` on a
cluster): the shard bounds, the genome payload a worker receives (connection genomes as packed mask bits) with
each genome's env seed, so that every individual gets the episode the one-process evaluator gives it, and
:class:`ShardWorker`.
"""

from __future__ import annotations

import copy
import math
import resource

import numpy as np
import torch

from spn_torchrl.envs import make_batched_env
from spn_torchrl.evaluation.rollout import Episodes, PopulationEvaluator
from spn_torchrl.seeds import slot_seeds
from spn_torchrl.snn.observations import Norm
from spn_torchrl.snn.policies import PopulationSPN

# returns, steps, spikes of one shard (and, with normalised observations, its slots' observation moments)
Results = tuple[np.ndarray, ...]
ShardNorm = tuple[np.ndarray, np.ndarray] | None  # one shard's (mean, inv_std) [b, n] float32, or None


def shard_bounds(count: int, parts: int) -> list[tuple[int, int]]:
    """``parts`` contiguous [start, stop) ranges covering ``count`` items, sizes differing by at most one
    (the first ``count % parts`` get one more). For ``count <= population`` every range fits in the
    matching range of the population, so worker i's env always holds shard i."""
    base, extra = divmod(count, parts)
    bounds, start = [], 0
    for i in range(parts):
        stop = start + base + (i < extra)
        bounds.append((start, stop))
        start = stop
    return bounds


def encode_genomes(spn: PopulationSPN, genomes: torch.Tensor) -> np.ndarray:
    """What a worker receives for a genome set [B, D]: connection genomes as their masks, packed 8 genes a
    byte ([B, ceil(D/8)] uint8: a mask is all a connection genome decides); weight genomes as float32 [B, D]."""
    if spn.genome_kind == "connections":
        mask1, mask2 = spn.masks(genomes)
        return np.packbits(torch.cat([mask1.flatten(1), mask2.flatten(1)], 1).numpy(), axis=1)
    return np.ascontiguousarray(genomes.detach().to(torch.float32).cpu().numpy())


def shard_requests(
    spn: PopulationSPN,
    genomes: torch.Tensor,
    seeds: int | np.ndarray,
    parts: int,
    capacity: int,
    holders: str,
    norm: Norm | None = None,
    runs: np.ndarray | None = None,
) -> list[tuple[int, int, int, np.ndarray, np.ndarray, ShardNorm, np.ndarray | None]]:
    """What each of ``parts`` workers gets for a genome set: (worker, start, stop, its encoded genomes, their env
    seeds, their observation normalisation or None, their runs or None) for every non-empty shard; ValueError
    naming ``holders`` past ``capacity``."""
    count = genomes.shape[0]
    if not 0 < count <= capacity:
        raise ValueError(f"the {holders} hold {capacity} individuals, got {count} genomes")
    payload, seeds = encode_genomes(spn, genomes), slot_seeds(seeds, count)
    rows = None if norm is None else [t.to(torch.float32).expand(count, -1).contiguous().numpy() for t in norm]

    def part(start: int, stop: int) -> ShardNorm:
        return None if rows is None else (rows[0][start:stop], rows[1][start:stop])

    bounds = enumerate(shard_bounds(count, parts))
    return [
        (
            i,
            start,
            stop,
            payload[start:stop],
            seeds[start:stop],
            part(start, stop),
            None if runs is None else runs[start:stop],
        )
        for i, (start, stop) in bounds
        if stop > start
    ]


def decode_genomes(payload: np.ndarray, genome_kind: str, genome_size: int) -> torch.Tensor:
    """Genomes [B, D] that give the SPN exactly the masks (or weights) :func:`encode_genomes` sent."""
    if genome_kind == "connections":
        bits = torch.from_numpy(np.unpackbits(payload, axis=1, count=genome_size).astype(bool))
        # scores of +-inf give sigmoid 1 or 0: the same mask for any threshold in (0, 1)
        return torch.where(bits, math.inf, -math.inf)
    return torch.tensor(payload)


def without_genomes(spn: PopulationSPN) -> PopulationSPN:
    """What a worker receives once: the SPN with its fixed weights only (the effective weights of an
    earlier genome set would only add bytes)."""
    bare = copy.copy(spn)
    bare.w1_eff = bare.w2_eff = bare.obs_norm = None
    return bare


def merge(parts: list[Results]) -> Episodes:
    """The episodes of the whole genome set from its shards' results, in shard order."""
    return Episodes(*(torch.from_numpy(np.concatenate(arrays)) for arrays in zip(*parts)))


class ShardWorker:
    """One shard's batched env of ``capacity`` slots and the SPN; evaluates shards of encoded genomes."""

    def __init__(
        self, spn: PopulationSPN, env_id: str, capacity: int, backend: str, threads: int, max_episode_steps: int
    ) -> None:
        torch.set_num_threads(1)
        env = make_batched_env(env_id, capacity, backend=backend, threads=threads)
        self.evaluator = PopulationEvaluator(env, spn, max_episode_steps)
        self.genome_kind, self.genome_size = spn.genome_kind, spn.genome_size

    def ready(self) -> int:
        return self.evaluator.size

    def evaluate(
        self, payload: np.ndarray, seeds: np.ndarray, norm: ShardNorm = None, runs: np.ndarray | None = None
    ) -> Results:
        genomes = decode_genomes(payload, self.genome_kind, self.genome_size)
        episodes = self.evaluator(genomes, seeds, None if norm is None else tuple(map(torch.from_numpy, norm)), runs)
        results = episodes.returns.numpy(), episodes.steps.numpy(), episodes.spikes.numpy()
        return results if norm is None else results + tuple(t.numpy() for t in episodes.moments)

    def peak_memory_mb(self) -> float:
        """This process's peak resident memory."""
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024

    def physics_seconds(self) -> float | None:
        """Wall time this shard's env spent inside its batched physics call (None: not a mujoco_batch env)."""
        return getattr(self.evaluator.env, "physics_seconds", None)
