"""Evolving Connectivity's NES on Bernoulli connection probabilities, as pure tensor operations (no env).

Each of ``ec.py``'s steps (github.com/imoneoi/EvolvingConnectivity at 3e61be4; lines cited in
:class:`~spn_torchrl.config.ECConfig`): masks sampled ``uniform < p``, centered-rank fitness, the NES gradient
``mean_i w_i (x_i - p)``, an Adam ascent step and the clip of p to ``[eps, 1 - eps]``; the deterministic mask is
``p > 0.5``. Masks travel to the evaluators as connection genomes: scores of +inf (a synapse) or -inf (none), the
same mask for any ``snn.score_threshold`` in (0, 1).
"""

from __future__ import annotations

import math
from typing import Any

import torch

from spn_torchrl.config import ECConfig


def centered_rank(fitness: torch.Tensor) -> torch.Tensor:
    """Ranks scaled to [-0.5, 0.5]: ``rank / (N - 1) - 0.5`` (ties ranked in population order, as JAX's stable
    argsort ranks them)."""
    ranks = torch.argsort(torch.argsort(fitness, stable=True), stable=True)
    return ranks.to(torch.float32) / (fitness.numel() - 1) - 0.5


def nes_gradient(p: torch.Tensor, masks: torch.Tensor, weights: torch.Tensor) -> torch.Tensor:
    """The ascent direction on p [D] from masks [N, D] and their fitness weights [N]: ``mean_i w_i (x_i - p)``."""
    return (weights[:, None] * (masks.to(p.dtype) - p)).mean(dim=0)


def adam_state(size: int) -> dict[str, Any]:
    """Adam's state before the first step: zero moments, zero steps."""
    return {"m": torch.zeros(size), "v": torch.zeros(size), "t": 0}


def adam_step(
    gradient: torch.Tensor, state: dict[str, Any], b1: float, b2: float, eps: float
) -> tuple[torch.Tensor, dict[str, Any]]:
    """optax.scale_by_adam's direction for ``gradient`` and the state after it (bias-corrected moments,
    ``m_hat / (sqrt(v_hat) + eps)``)."""
    t = state["t"] + 1
    m = b1 * state["m"] + (1 - b1) * gradient
    v = b2 * state["v"] + (1 - b2) * gradient * gradient
    m_hat = m / (1 - b1**t)
    v_hat = v / (1 - b2**t)
    return m_hat / (v_hat.sqrt() + eps), {"m": m, "v": v, "t": t}


def update(
    p: torch.Tensor, adam: dict[str, Any], masks: torch.Tensor, fitness: torch.Tensor, algo: ECConfig
) -> tuple[torch.Tensor, dict[str, Any]]:
    """One generation's step on p: centered rank, NES gradient, Adam ascent with ``algo.lr``, clip to
    ``[algo.eps, 1 - algo.eps]``; returns the new p and Adam state."""
    gradient = nes_gradient(p, masks, centered_rank(fitness))
    direction, adam = adam_step(gradient, adam, algo.adam_b1, algo.adam_b2, algo.adam_eps)
    return torch.clamp(p + algo.lr * direction, algo.eps, 1 - algo.eps), adam


def sample_masks(p: torch.Tensor, count: int, generator: torch.Generator) -> torch.Tensor:
    """``count`` masks [count, D] drawn independently: synapse j exists where ``uniform < p_j``."""
    return torch.rand((count, p.numel()), generator=generator) < p


def deterministic_mask(p: torch.Tensor) -> torch.Tensor:
    """The evaluation mask [D]: a synapse wherever ``p > 0.5``."""
    return p > 0.5


def mask_genomes(masks: torch.Tensor) -> torch.Tensor:
    """Connection genomes of masks (+inf where a synapse exists, -inf where not), the evaluators' input."""
    return torch.where(masks, math.inf, -math.inf)


def genome_masks(genomes: torch.Tensor) -> torch.Tensor:
    """The masks that :func:`mask_genomes` encoded."""
    return genomes > 0


class ECStep:
    """The EC side of the evolution loop (:mod:`spn_torchrl.training.evolve`): its one elite candidate is the
    deterministic mask of the p that sampled the generation; its step updates p and samples the next masks."""

    elite_from_population = False

    def __init__(self, algo: ECConfig, state: dict[str, Any]) -> None:
        self.algo = algo
        self.p, self.adam = state["p"], dict(state["adam"])

    def elite_pool(self, population: torch.Tensor, fitness: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """The genomes the elite is picked from and the candidates' indices: the deterministic mask alone."""
        return mask_genomes(deterministic_mask(self.p))[None], torch.zeros(1, dtype=torch.long)

    def advance(self, population: torch.Tensor, fitness: torch.Tensor, generator: torch.Generator) -> torch.Tensor:
        """Update p from this generation's masks and fitness, then sample the next generation's masks."""
        self.p, self.adam = update(self.p, self.adam, genome_masks(population), fitness, self.algo)
        return mask_genomes(sample_masks(self.p, self.algo.population, generator))

    def state(self) -> dict[str, Any]:
        """What a checkpoint adds for EC: p and Adam's state."""
        return {"p": self.p, "adam": dict(self.adam)}


def initial_state(algo: ECConfig, size: int, generator: torch.Generator) -> dict[str, Any]:
    """Generation 0: p at ``algo.p_init``, Adam's zero state and the first masks drawn from ``generator``."""
    p = torch.full((size,), float(algo.p_init))
    return {"p": p, "adam": adam_state(size), "population": mask_genomes(sample_masks(p, algo.population, generator))}
