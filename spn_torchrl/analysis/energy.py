"""The paper's energy and data-efficiency model (SPEC.md, "Energy model"), as plain functions.

Units: picojoules (pJ), 45 nm figures e_MAC = 4.6 pJ, e_AC = 0.9 pJ.

Two counts of SPN operations:
- **dense** (paper-faithful, the default): every synapse of the fixed network counts, masked out or not;
- **mask-aware** (an extra, never instead of the paper's): only the synapses that exist count: layer 1 as
  MACs over its existing synapses, layer 2 as ACs over its existing synapses times the spike rate.

Spike rate: the paper's E_SPN figures fit a rate **per simulation step** (hidden spikes / (neurons * T'),
averaged over env steps), which is what progress.csv logs as ``spike_rate``; ``rate_per_env_step`` converts
to the other reading (spikes per neuron per env step, i.e. over the whole window of T' steps).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

E_MAC_PJ = 4.6
E_AC_PJ = 0.9
HIDDEN = 64
PPO_STEPS = 1_000_000
PPO_EPOCHS = 25


def layer_ops(sizes: Sequence[int]) -> list[int]:
    """#OP per layer of a dense net with layer widths ``sizes`` (e.g. [n, 64, m]): f_in * f_out each."""
    return [f_in * f_out for f_in, f_out in zip(sizes[:-1], sizes[1:])]


def e_dpn(n: int, m: int, hidden: int = HIDDEN) -> float:
    """Inference energy of the DPN policy n -> hidden -> m, all MACs (pJ per forward pass)."""
    return sum(layer_ops([n, hidden, m])) * E_MAC_PJ


def e_dvn(n: int, hidden: int = HIDDEN) -> float:
    """Inference energy of the value net n -> hidden -> 1, all MACs (pJ per forward pass)."""
    return sum(layer_ops([n, hidden, 1])) * E_MAC_PJ


def e_spn(n: int, m: int, rate: float, hidden: int = HIDDEN) -> float:
    """Dense (paper) SPN inference energy: layer 1 as n*hidden MACs, layer 2 as rate*hidden*m ACs.

    ``rate`` is hidden spikes per neuron per simulation step (the reading the paper's numbers fit).
    """
    first, second = layer_ops([n, hidden, m])
    return first * E_MAC_PJ + rate * second * E_AC_PJ


def e_spn_masked(synapses_l1: float, synapses_l2: float, rate: float) -> float:
    """Mask-aware SPN inference energy: MACs over existing layer-1 synapses, rate * existing layer-2 ACs."""
    return synapses_l1 * E_MAC_PJ + rate * synapses_l2 * E_AC_PJ


def rate_per_env_step(rate_per_sim_step: float, time_steps: int = 4) -> float:
    """Spikes per neuron per env step (the whole window of T' simulation steps) from the per-step rate."""
    return rate_per_sim_step * time_steps


def ppo_passes(steps: int = PPO_STEPS, epochs: int = PPO_EPOCHS) -> tuple[int, int]:
    """(forward, backward) passes per network of PPO: one forward per collected step, then ``epochs``
    forward+backward sweeps over the data (1e6 steps, 25 epochs: 2.6e7 and 2.5e7, the paper's table)."""
    return steps * (1 + epochs), steps * epochs


def e_optim_ppo(
    n: int,
    m: int,
    policy_forward: float,
    policy_backward: float,
    value_forward: float | None = None,
    value_backward: float | None = None,
    hidden: int = HIDDEN,
) -> float:
    """E_PPO = E_DPN*(N_fwd + N_bwd) + E_DVN*(N_fwd + N_bwd); the value counts default to the policy's."""
    value_forward = policy_forward if value_forward is None else value_forward
    value_backward = policy_backward if value_backward is None else value_backward
    return e_dpn(n, m, hidden) * (policy_forward + policy_backward) + e_dvn(n, hidden) * (
        value_forward + value_backward
    )


def e_optim_ga(e_spn_pj: float, env_steps: float) -> float:
    """E_GA = E_SPN * (env steps used): one SPN forward pass per env step, no backward pass."""
    return e_spn_pj * env_steps


def first_generation_at(returns: Sequence[float], level: float) -> int | None:
    """G: the first generation (1-based) whose return reaches ``level``, or None if none does."""
    for generation, value in enumerate(returns, start=1):
        if value >= level:
            return generation
    return None


def data_efficiency(generations: int, steps_per_gen: float, ppo_steps: int = PPO_STEPS) -> tuple[float, float]:
    """(E, gamma): E = G * A env steps, gamma = E / PPO's env steps (1e6)."""
    used = generations * steps_per_gen
    return used, used / ppo_steps


def sig(value: float | None, digits: int = 3) -> str:
    """A number in the paper's style (3 significant digits, e-notation for large values); '-' for None."""
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if value != 0 and (abs(value) >= 1e3 or abs(value) < 1e-2):
        mantissa, exponent = f"{value:.{digits - 1}e}".split("e")
        return f"{mantissa}e{int(exponent)}"
    return f"{value:.{digits}g}"


def inference_energy(
    n: int, m: int, hidden: int, rate: float, synapses_l1: float, synapses_l2: float
) -> dict[str, float]:
    """SPN inference energy per env step (pJ): the paper's dense count and the mask-aware one, for a hidden spike
    rate per simulation step and the synapses that exist in each layer."""
    return {"dense_pj": e_spn(n, m, rate, hidden), "mask_aware_pj": e_spn_masked(synapses_l1, synapses_l2, rate)}
