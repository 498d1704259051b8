"""LIF and LI neuron dynamics of the SPN (SPEC.md), as plain tensor functions."""

from __future__ import annotations

import math
from collections.abc import Callable

import torch

from spn_torchrl.config import SNNConfig

SpikeFn = Callable[[torch.Tensor, float], torch.Tensor]

SNN = SNNConfig()  # the paper's constants (SPEC.md), the functions' defaults
DECAY, V_TH, TIME_STEPS = SNN.decay, SNN.v_threshold, SNN.time_steps


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


def _ordered(x: torch.Tensor) -> torch.Tensor:
    """float32 -> int64 keys in the order of the values (-0.0 and 0.0 share one)."""
    bits = x.view(torch.int32).long()
    return torch.where(bits >= 0, bits, -(bits & 0x7FFFFFFF))


def _float32(key: torch.Tensor) -> torch.Tensor:
    """The inverse of :func:`_ordered`."""
    return torch.where(key >= 0, key, (-key) | -(2**31)).to(torch.int32).view(torch.float32)


def spike_thresholds(time_steps: int = TIME_STEPS, decay: float = DECAY, v_th: float = V_TH) -> torch.Tensor:
    """[T] float32: entry t is the least current under which a LIF neuron at rest has spiked within its first
    t + 1 steps (+inf: no finite current does). Exact for :func:`lif_step`'s float32 arithmetic.

    Without a spike yet, the potential at each step is non-decreasing in the current (``decay`` >= 0 and
    rounding are monotone), so the currents that spike by step t are those above a threshold, which a
    bisection over the float32 values finds.
    """
    big = torch.finfo(torch.float32).max
    lo = torch.full((time_steps,), int(_ordered(torch.tensor([-big]))[0]))
    hi = torch.full((time_steps,), int(_ordered(torch.tensor([big]))[0]))
    steps = torch.arange(time_steps)

    def spiked(key: torch.Tensor) -> torch.Tensor:
        """Whether current ``key[t]`` has spiked by step t + 1 (each entry its own step)."""
        current = _float32(key)
        v, fired = current, current > v_th
        none = torch.zeros_like(current)
        for t in range(1, time_steps):
            v, _ = lif_step(v, none, current, decay, v_th)  # the potential while no spike has reset it
            fired = torch.where(steps >= t, fired | (v > v_th), fired)
        return fired

    always, never = spiked(lo), ~spiked(hi)
    while bool(((hi - lo) > 1).any()):
        mid = (lo + hi) // 2
        up = spiked(mid)
        hi, lo = torch.where(up, mid, hi), torch.where(up, lo, mid)
    thresholds = _float32(hi)
    thresholds[always] = -math.inf
    thresholds[never] = math.inf
    return thresholds


def spike_pattern(time_steps: int = TIME_STEPS) -> torch.Tensor:
    """[T, T] matrix that maps the indicators ``current >= spike_thresholds()`` ([T, ...]) to the spikes.

    A neuron under a constant current that first spikes at step tau restarts from the state of step 1
    (the reset leaves exactly the current), so it spikes at every multiple of tau: the spike at step s is
    the sum over the divisors tau of s of [tau is the first spike step] = [spiked by tau] - [spiked by tau - 1].
    """
    s = torch.arange(1, time_steps + 1)
    divides = (s[:, None] % s[None, :] == 0).float()  # [s, tau]: tau divides s
    return divides - torch.cat([divides[:, 1:], torch.zeros(time_steps, 1)], 1)


def threshold_spikes(current: torch.Tensor, thresholds: torch.Tensor, pattern: torch.Tensor) -> torch.Tensor:
    """What :func:`lif_spikes` (Heaviside) gives for every finite or NaN ``current`` [..., h], as spikes
    [..., T, h] (a strided view), from :func:`spike_thresholds` and :func:`spike_pattern`: one comparison
    and one small matrix product instead of T LIF steps."""
    t = thresholds.shape[0]
    spiked = torch.ge(current.reshape(1, -1), thresholds[:, None], out=current.new_empty(t, current.numel()))
    spikes = torch.mm(pattern, spiked)  # sums of a few 0/1 terms: exact
    return spikes.view(t, *current.shape).movedim(0, -2)


def spn_dynamics(
    w1: torch.Tensor,
    w2: torch.Tensor,
    obs: torch.Tensor,
    time_steps: int = TIME_STEPS,
    decay: float = DECAY,
    v_th: float = V_TH,
    spike_fn: SpikeFn = heaviside,
    hidden_spikes: Callable[[torch.Tensor], torch.Tensor] | None = None,
) -> tuple[torch.Tensor, torch.Tensor]:
    """Run the SPN for one environment step of a population.

    w1 [P, n, h] and w2 [P, h, m] are the effective (masked) weights, input-major (the transposes of the
    [h, n] and [m, h] synapse matrices), obs [P, n] the observations held constant for ``time_steps``
    steps from a zero state. Returns the max over time of the output potentials [P, m] and the hidden
    spike count per individual [P]. ``spike_fn`` lets a gradient through the spikes (see
    :mod:`spn_torchrl.snn.surrogate`); its forward values must be the Heaviside step's. ``hidden_spikes`` maps
    the hidden currents [P, h] to the spikes [P, T, h] in place of :func:`lif_spikes` (e.g.
    :func:`threshold_spikes`, the same values without a gradient).
    """
    current = torch.bmm(obs.unsqueeze(1), w1).squeeze(1)
    if hidden_spikes is None:
        spikes = lif_spikes(current, time_steps, decay, v_th, spike_fn)  # [P, T, h]
    else:
        spikes = hidden_spikes(current)
    inputs = torch.bmm(spikes, w2)  # [P, T, m]: all time steps' inputs at once
    v2 = inputs[:, 0]  # the first step from rest: decay * 0 + input
    out = v2
    for t in range(1, time_steps):
        v2 = li_step(v2, inputs[:, t], decay)
        out = torch.maximum(out, v2)
    return out, spikes.sum((1, 2))
