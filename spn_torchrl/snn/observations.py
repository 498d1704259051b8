"""Observation normalisation (``normalize_observations=true``, beyond the paper): running mean and std, as
Evolving Connectivity's ``ec.py`` keeps them (github.com/imoneoi/EvolvingConnectivity at 3e61be4, l. 125, 190,
263) with brax's ``running_statistics`` (``brax/training/acme/running_statistics.py``).

The running statistics are brax's batched Welford update, in float64: ``count += B``,
``mean += sum(x - mean) / count``, ``summed_variance += sum((x - old_mean) * (x - new_mean))``,
``std = clip(sqrt(max(summed_variance, 0) / count), 1e-6, 1e6)``; they start at count 0, mean 0, std 1. A batch
reaches them as its moments (count, sum and sum of squares per observation element), which the evaluators sum
per env slot, so that a population cut into any shards gives the same statistics. A policy applies
``(x - mean) * inv_std`` in float32 (brax: ``(x - mean) / std``; the product is what a NIR ``Scale`` node
computes, so that an exported graph acts bit for bit like the SPN).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

STD_MIN, STD_MAX = 1e-6, 1e6  # brax running_statistics.update's std_min_value, std_max_value

Norm = tuple[torch.Tensor, torch.Tensor]  # (mean, inv_std), float32, what a policy applies


def initial_stats(size: int) -> dict[str, Any]:
    """The statistics before any observation (brax ``init_state``): count 0, mean 0, std 1."""
    zeros = torch.zeros(size, dtype=torch.float64)
    return {"count": 0, "mean": zeros, "summed_variance": zeros.clone(), "std": torch.ones(size, dtype=torch.float64)}


def moments(observations: torch.Tensor) -> tuple[int, torch.Tensor, torch.Tensor]:
    """A batch [B, n] as (B, sum [n], sum of squares [n]), in float64."""
    x = observations.detach().to(torch.float64).reshape(-1, observations.shape[-1])
    return x.shape[0], x.sum(0), (x * x).sum(0)


def slot_moments(
    count: torch.Tensor, total: torch.Tensor, squares: torch.Tensor
) -> tuple[int, torch.Tensor, torch.Tensor]:
    """The moments of a batch from its env slots' ([B], [B, n], [B, n]), summed over the slots in one order
    whatever the thread count (numpy's pairwise sum)."""
    return int(count.sum()), _slot_sum(total), _slot_sum(squares)


def _slot_sum(x: torch.Tensor) -> torch.Tensor:
    return torch.from_numpy(np.sum(x.numpy(), axis=0))


def update(stats: dict[str, Any], batch: tuple[int, torch.Tensor, torch.Tensor]) -> dict[str, Any]:
    """The statistics after a batch given by its moments (brax's batched Welford; a batch of 0 changes nothing)."""
    size, total, squares = batch
    if size == 0:
        return stats
    count = stats["count"] + size
    old = stats["mean"]
    new = old + (total - size * old) / count
    # sum((x - old) * (x - new)) written with the batch's sums
    summed = stats["summed_variance"] + (squares - (old + new) * total + size * old * new)
    std = torch.clamp(torch.sqrt(torch.clamp(summed, min=0) / count), STD_MIN, STD_MAX)
    return {"count": count, "mean": new, "summed_variance": summed, "std": std}


def policy_norm(stats: dict[str, Any]) -> Norm:
    """What a policy applies: (mean, 1 / std) in float32."""
    return stats["mean"].to(torch.float32), (1.0 / stats["std"]).to(torch.float32)


def normalize(observations: torch.Tensor, norm: Norm | None) -> torch.Tensor:
    """``(x - mean) * inv_std`` (``norm`` None: ``x`` unchanged)."""
    if norm is None:
        return observations
    mean, inv_std = norm
    return (observations - mean) * inv_std


class ObservationNormalizer(nn.Module):
    """A network's first layer that applies a :data:`Norm` held in buffers (PPO's actor and critic); the
    running statistics that set it live in the run's state (:meth:`set`)."""

    def __init__(self, size: int) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(size))
        self.register_buffer("inv_std", torch.ones(size))

    def set(self, norm: Norm) -> None:
        self.mean.copy_(norm[0])
        self.inv_std.copy_(norm[1])

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return normalize(observations, (self.mean, self.inv_std))
