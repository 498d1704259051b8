"""The paper's genetic algorithm as pure tensor operations on genomes and fitnesses (no env)."""

from __future__ import annotations

import torch


def mirrored(center: torch.Tensor, sigma: float, generator: torch.Generator) -> torch.Tensor:
    """Two children per row of ``center`` [K, D]: ``c + sigma*eps`` then ``c - sigma*eps`` -> [2K, D]."""
    eps = torch.randn(center.shape, generator=generator, dtype=center.dtype, device=center.device)
    return torch.stack([center + sigma * eps, center - sigma * eps], dim=1).reshape(-1, center.shape[1])


def initial_population(
    size: int, dim: int, sigma: float, generator: torch.Generator, center: torch.Tensor | None = None
) -> torch.Tensor:
    """Generation 0: ``size/2`` mirrored pairs around ``center`` (zeros, as in the paper) -> [size, dim]."""
    base = torch.zeros(dim) if center is None else center.reshape(dim).float()
    return mirrored(base.expand(size // 2, dim), sigma, generator)


def ranking(fitness: torch.Tensor) -> torch.Tensor:
    """Indices from best to worst fitness; ties keep population order."""
    return torch.sort(fitness, descending=True, stable=True).indices


def num_parents(size: int, truncation: float) -> int:
    """How many of the best individuals truncation selection keeps (at least one)."""
    return max(1, int(size * truncation))


def next_generation(
    population: torch.Tensor,
    fitness: torch.Tensor,
    *,
    sigma: float,
    truncation: float,
    generator: torch.Generator,
    elitism: int = 0,
) -> torch.Tensor:
    """Truncation selection, parents drawn uniformly with replacement, mirrored children.

    ``elitism > 0`` (an option, not the paper's GA) copies the best ``elitism`` individuals unchanged
    over the last children.
    """
    size = population.shape[0]
    order = ranking(fitness)
    parents = order[: num_parents(size, truncation)]
    picks = parents[torch.randint(len(parents), (size // 2,), generator=generator)]
    children = mirrored(population[picks], sigma, generator)
    if elitism > 0:
        children[size - elitism :] = population[order[:elitism]]
    return children


def elite_candidates(fitness: torch.Tensor, k: int) -> torch.Tensor:
    """Indices of the ``k`` best individuals by single-episode fitness, best first."""
    return ranking(fitness)[:k]


def reevaluation_genomes(population: torch.Tensor, candidates: torch.Tensor, episodes: int) -> torch.Tensor:
    """The genomes of the elite re-evaluation: each candidate ``episodes`` times in a row, [k * E, D]."""
    return population[candidates].repeat_interleave(episodes, 0)


def pick_elite(candidates: torch.Tensor, episode_returns: torch.Tensor) -> tuple[int, float]:
    """The candidate with the best mean over its re-evaluation episodes [k, E]: (its index, its mean)."""
    means = episode_returns.mean(dim=1)
    best = int(torch.argmax(means))
    return int(candidates[best]), float(means[best])
