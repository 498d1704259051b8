"""The paper's genetic algorithm as pure tensor operations on genomes and fitnesses (no env), and its step of the
evolution loop."""

from __future__ import annotations

from typing import Any

import torch

from spn_torchrl.config import GAConfig


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


class GAStep:
    """The GA side of the evolution loop (:mod:`spn_torchrl.training.evolve`): its elite candidates are the
    ``elite_candidates`` best individuals; its step is :func:`next_generation`."""

    elite_from_population = True

    def __init__(self, algo: GAConfig, state: dict[str, Any]) -> None:
        self.algo = algo

    def elite_pool(self, population: torch.Tensor, fitness: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The genomes the elite is picked from and the candidates' indices: the population and its best k."""
        return population, elite_candidates(fitness, self.algo.elite_candidates)

    def advance(self, population: torch.Tensor, fitness: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """The next generation."""
        algo = self.algo
        return next_generation(
            population,
            fitness,
            sigma=algo.sigma,
            truncation=algo.truncation,
            generator=generator,
            elitism=algo.elitism,
        )

    def state(self) -> dict[str, Any]:
        """The GA keeps no state beyond the population and the generator."""
        return {}
