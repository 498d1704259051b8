"""LIF and LI neuron dynamics of the SPN (SPEC.md), as plain tensor functions."""

from __future__ import annotations

from typing import Callable

import torch

SpikeFn = Callable[[torch.Tensor, float], torch.Tensor]

DECAY = 0.75
V_TH = 0.5
TIME_STEPS = 4


def heaviside(v: torch.Tensor, v_th: float) -> torch.Tensor:
    """Spikes of potentials ``v``: ``v > v_th`` (strict), as floats."""
    return (v > v_th).to(v.dtype)


def lif_step(
    v: torch.Tensor,
    spikes: torch.Tensor,
    current: torch.Tensor,
    decay: float = DECAY,
    v_th: float = V_TH,
    spike_fn: SpikeFn = heaviside,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One LIF step: the previous spike resets its neuron now; a spike is ``spike_fn(v, v_th)``
    (``v > v_th`` strict by default; a surrogate-gradient function gives the same values)."""
    v = decay * v * (1.0 - spikes) + current
    return v, spike_fn(v, v_th)


def li_step(v: torch.Tensor, current: torch.Tensor, decay: float = DECAY) -> torch.Tensor:
    """One LI (leaky integrate, non-spiking) step."""
    return decay * v + current


def lif_spikes(
    current: torch.Tensor,
    time_steps: int = TIME_STEPS,
    decay: float = DECAY,
    v_th: float = V_TH,
    spike_fn: SpikeFn = heaviside,
) -> list[torch.Tensor]:
    """Spikes of a LIF layer at each of ``time_steps`` simulation steps, from a zero state, under a constant
    input ``current``."""
    v = torch.zeros_like(current)
    s = torch.zeros_like(current)
    spikes = []
    for _ in range(time_steps):
        v, s = lif_step(v, s, current, decay, v_th, spike_fn)
        spikes.append(s)
    return spikes


def spn_dynamics(
    w1: torch.Tensor,
    w2: torch.Tensor,
    obs: torch.Tensor,
    time_steps: int = TIME_STEPS,
    decay: float = DECAY,
    v_th: float = V_TH,
    spike_fn: SpikeFn = heaviside,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Run the SPN for one environment step of a population.

    w1 [P, h, n] and w2 [P, m, h] are the effective (masked) weights, obs [P, n] the observations held
    constant for ``time_steps`` steps from a zero state. Returns the max over time of the output
    potentials [P, m] and the hidden spike count per individual [P]. ``spike_fn`` lets a gradient through
    the spikes (see :mod:`spn_torchrl.surrogate`); its forward values must be the Heaviside step's.
    """
    current = torch.bmm(w1, obs.unsqueeze(-1)).squeeze(-1)
    spikes = lif_spikes(current, time_steps, decay, v_th, spike_fn)
    v2 = obs.new_zeros(w2.shape[0], w2.shape[1])
    out = None
    for s1 in spikes:
        v2 = li_step(v2, torch.bmm(w2, s1.unsqueeze(-1)).squeeze(-1), decay)
        out = v2 if out is None else torch.maximum(out, v2)
    return out, sum(spikes).sum(-1)
