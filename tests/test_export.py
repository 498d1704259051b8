"""``python -m spn_torchrl.export``: the NIR graph, read back and simulated step by step, acts like the SPN."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from spn_torchrl.tools.elite import load_elite
from spn_torchrl.tools.play import run_episode

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

nir = pytest.importorskip("nir")
ROOT = Path(__file__).resolve().parents[1]


def topological(graph) -> list[str]:
    order, seen = [], set()

    def visit(name):
        if name in seen:
            return
        seen.add(name)
        for src, dst in graph.edges:
            if dst == name:
                visit(src)
        order.append(name)

    for name in graph.nodes:
        visit(name)
    return order


def simulate(graph, observations: np.ndarray) -> np.ndarray:
    """Run a NIR graph (Input, Linear, Affine, Scale, LIF, LI, Output) on a batch of observations [B, n], each from zero state for
    ``time_steps`` forward-Euler steps of ``dt``, reading out the max over time of the output (graph metadata)."""
    dt, steps = float(graph.metadata["dt"]), int(graph.metadata["time_steps"])
    assert graph.metadata["readout"] == "max_over_time"
    x = observations.astype(np.float32)
    order = topological(graph)
    state = {
        name: np.zeros((x.shape[0], node.tau.shape[0]), np.float32)
        for name, node in graph.nodes.items()
        if isinstance(node, (nir.LIF, nir.LI))
    }
    readout = None
    for _ in range(steps):
        values = {}
        for name in order:
            node = graph.nodes[name]
            inputs = [values[src] for src, dst in graph.edges if dst == name]
            signal = sum(inputs) if inputs else None
            if isinstance(node, nir.Input):
                values[name] = x
            elif isinstance(node, nir.Linear):
                values[name] = signal @ node.weight.astype(np.float32).T
            elif isinstance(node, nir.Affine):
                values[name] = signal @ node.weight.astype(np.float32).T + node.bias.astype(np.float32)
            elif isinstance(node, nir.Scale):
                values[name] = signal * node.scale.astype(np.float32)
            elif isinstance(node, (nir.LIF, nir.LI)):
                decay = (1.0 - dt / node.tau).astype(np.float32)  # forward Euler, coefficients first
                gain = (dt / node.tau * node.r).astype(np.float32)
                leak = (dt / node.tau * node.v_leak).astype(np.float32)
                v = decay * state[name] + gain * signal + leak
                if isinstance(node, nir.LIF):
                    spikes = v > node.v_threshold
                    v = np.where(spikes, node.v_reset.astype(np.float32), v)
                    values[name] = spikes.astype(np.float32)
                else:
                    values[name] = v
                state[name] = v
            elif isinstance(node, nir.Output):
                values[name] = signal
                readout = signal if readout is None else np.maximum(readout, signal)
            else:
                raise TypeError(f"the test simulator does not know {type(node).__name__}")
    return readout


def export(run_dir: Path, out: Path, *args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "spn_torchrl.export", str(run_dir), "--format", "nir", str(out), *args]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)


def recorded_observations(elite, count: int) -> torch.Tensor:
    observations, seed = [], 0
    while sum(len(o) for o in observations) < count:
        observations.append(run_episode(elite, seed).observations)
        seed += 1
    return torch.cat(observations)[:count]


def actions_of(graph, observations: torch.Tensor) -> torch.Tensor:
    out = torch.as_tensor(simulate(graph, observations.numpy()))
    if graph.metadata["action"] == "argmax":
        return out.argmax(-1)
    return torch.clamp(
        out, torch.as_tensor(graph.metadata["action_low"]), torch.as_tensor(graph.metadata["action_high"])
    )


@pytest.mark.parametrize("run", ["halfcheetah_run", "cartpole_run"])
def test_nir_round_trip_acts_like_the_spn(run, request, tmp_path):
    run_dir = request.getfixturevalue(run)
    out = tmp_path / "elite.nir"
    done = export(run_dir, out)
    assert done.returncode == 0, done.stderr
    graph = nir.read(out)
    elite = load_elite(run_dir)
    x1, x2 = elite.masks
    assert np.array_equal(graph.nodes["linear_1"].weight != 0, x1.numpy() & (elite.state["w1"] != 0).numpy())
    assert np.array_equal(graph.nodes["linear_2"].weight, elite.weights[1].numpy())
    observations = recorded_observations(elite, 1000)
    elite.spn.set_genomes(elite.genome[None].expand(len(observations), -1))
    expected, _ = elite.spn(observations)
    # float32 matrix products round by the kernel that sums them (numpy's here, torch's bmm in the SPN): the
    # actions agree to rounding, not always bit for bit
    torch.testing.assert_close(actions_of(graph, observations), expected, rtol=0, atol=1e-5)


def test_export_errors_are_one_sentence(cartpole_run, tmp_path):
    done = export(tmp_path / "nowhere", tmp_path / "x.nir")
    assert done.returncode != 0 and "does not exist" in done.stderr and "Traceback" not in done.stderr
    done = export(cartpole_run, tmp_path / "x.nir", "--generation", "0")
    assert done.returncode != 0 and "--generation must be in [1, 2]" in done.stderr


def test_export_to_a_directory_is_one_sentence(cartpole_run, tmp_path):
    done = export(cartpole_run, tmp_path)
    assert done.returncode == 1 and "Traceback" not in done.stderr
    assert done.stderr.strip().splitlines()[-1] == f"error: {tmp_path} is a directory, expected a file"
