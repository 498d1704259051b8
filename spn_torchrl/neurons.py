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
    return torch.gt(v, v_th, out=torch.empty_like(v))  # one kernel, no bool tensor to convert


def lif_step(
    v: torch.Tensor,
    spikes: torch.Tensor,
    current: torch.Tensor,
    decay: float = DECAY,
    v_th: float = V_TH,
    spike_fn: SpikeFn = heaviside,
) -> tuple[torch.Tensor, torch.Tensor]:
    """One LIF step ``v = decay * v * (1 - spikes) + current``: the previous spike resets its neuron now; a
    spike is ``spike_fn(v, v_th)`` (``v > v_th`` strict by default; a surrogate-gradient function gives
    the same values)."""
    # spikes are 0 or 1, so the fused multiply-add rounds exactly as the separate product and sum
    v = torch.addcmul(current, decay * v, 1.0 - spikes)
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
) -> torch.Tensor:
    """Spikes [..., time_steps, h] of a LIF layer from a zero state under a constant input ``current``
    [..., h]."""
    v = current  # the first step from rest: decay * 0 + current
    s = spike_fn(v, v_th)
    spikes = [s]
    for _ in range(time_steps - 1):
        v, s = lif_step(v, s, current, decay, v_th, spike_fn)
        spikes.append(s)
    return torch.stack(spikes, -2)


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

    w1 [P, n, h] and w2 [P, h, m] are the effective (masked) weights, input-major (the transposes of the
    [h, n] and [m, h] synapse matrices), obs [P, n] the observations held constant for ``time_steps``
    steps from a zero state. Returns the max over time of the output potentials [P, m] and the hidden
    spike count per individual [P]. ``spike_fn`` lets a gradient through the spikes (see
    :mod:`spn_torchrl.surrogate`); its forward values must be the Heaviside step's.
    """
    current = torch.bmm(obs.unsqueeze(1), w1).squeeze(1)
    spikes = lif_spikes(current, time_steps, decay, v_th, spike_fn)  # [P, T, h]
    inputs = torch.bmm(spikes, w2).transpose(0, 1).contiguous()  # [T, P, m]: all time steps' inputs at once
    v2 = inputs[0]  # the first step from rest: decay * 0 + input
    out = v2
    for t in range(1, time_steps):
        v2 = li_step(v2, inputs[t], decay)
        out = torch.maximum(out, v2)
    return out, spikes.sum((1, 2))
