import math

import pytest
import torch

from spn_torchrl.snn.neurons import (
    li_step,
    lif_spikes,
    lif_step,
    spike_pattern,
    spike_thresholds,
    spn_dynamics,
    threshold_spikes,
)


def one_neuron(w1: float, w2: float, obs: float):
    return spn_dynamics(torch.tensor([[[w1]]]), torch.tensor([[[w2]]]), torch.tensor([[obs]]))


def test_hand_computed_case():
    # v1: 0.3, 0.525 (spike), 0.3 (reset applied at this step), 0.525 (spike)
    # v2: 0, 2, 1.5, 3.125  -> max 3.125, two hidden spikes
    out, spikes = one_neuron(1.0, 2.0, 0.3)
    assert torch.allclose(out, torch.tensor([[3.125]]))
    assert spikes.tolist() == [2.0]


def test_threshold_is_strict():
    out, spikes = one_neuron(1.0, 1.0, 0.5)  # v1 = 0.5 at tau=1: no spike
    assert spikes.tolist() == [2.0]  # tau=2: 0.875 spikes, tau=3: 0.5 (reset) no, tau=4: 0.875 spikes


def test_output_max_excludes_initial_zero():
    # spikes at every step: v2 = -1, -1.75, ... so the max is -1, not the initial 0
    out, spikes = one_neuron(1.0, -1.0, 1.0)
    assert torch.allclose(out, torch.tensor([[-1.0]]))
    assert spikes.tolist() == [4.0]


def test_lif_reset_and_li_leak():
    v, s = lif_step(torch.tensor([0.8]), torch.tensor([1.0]), torch.tensor([0.1]))
    assert torch.allclose(v, torch.tensor([0.1])) and s.item() == 0.0
    v, s = lif_step(torch.tensor([0.8]), torch.tensor([0.0]), torch.tensor([0.1]))
    assert torch.allclose(v, torch.tensor([0.7])) and s.item() == 1.0
    assert torch.allclose(li_step(torch.tensor([2.0]), torch.tensor([1.0])), torch.tensor([2.5]))


def test_state_starts_at_zero_each_call():
    w1, w2, obs = torch.randn(3, 5, 64), torch.randn(3, 64, 2), torch.randn(3, 5)
    first = spn_dynamics(w1, w2, obs)
    second = spn_dynamics(w1, w2, obs)
    assert torch.equal(first[0], second[0]) and torch.equal(first[1], second[1])


@pytest.mark.parametrize(
    "time_steps,decay,v_th",
    [(4, 0.75, 0.5), (1, 0.75, 0.5), (7, 0.9, 0.3), (5, 0.0, 0.5), (6, 1.0, -0.2), (8, 0.5, 0.0)],
)
def test_threshold_spikes_equal_the_lif_steps(time_steps, decay, v_th):
    thresholds = spike_thresholds(time_steps, decay, v_th)
    pattern = spike_pattern(time_steps)
    finite = thresholds[thresholds.isfinite()]
    edges = torch.cat(
        [finite, torch.nextafter(finite, torch.tensor(-math.inf)), torch.nextafter(finite, torch.tensor(math.inf))]
    )
    generator = torch.Generator().manual_seed(0)
    current = torch.cat(
        [
            torch.randn(100_000, generator=generator) * 0.5,
            torch.rand(100_000, generator=generator) * 0.6 - 0.05,
            edges,
            torch.tensor([0.0, -0.0, math.nan, 1e30, -1e30, torch.finfo(torch.float32).tiny]),
        ]
    )
    current = torch.cat([current, torch.zeros((-len(current)) % 8)]).view(-1, 8)  # [N, h]
    want = lif_spikes(current, time_steps, decay, v_th)
    got = threshold_spikes(current, thresholds, pattern)
    assert got.shape == want.shape == (current.shape[0], time_steps, 8)
    assert torch.equal(got, want)


def test_spike_thresholds_of_the_paper():
    thresholds = spike_thresholds()
    assert thresholds[0] == torch.nextafter(torch.tensor(0.5), torch.tensor(1.0))  # strictly above v_th at step 1
    # without a spike: v = c (1 + 0.75 + ...): 0.5 / 1.75, 0.5 / 2.3125, 0.5 / 2.734375, up to rounding
    assert torch.allclose(thresholds[1:], torch.tensor([0.5 / 1.75, 0.5 / 2.3125, 0.5 / 2.734375]))
    assert torch.all(thresholds[1:] < thresholds[:-1])
    assert spike_thresholds(3, 0.5, math.inf).tolist() == [math.inf] * 3
