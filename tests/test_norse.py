"""A third-party simulator runs our NIR: Norse 1.1 (``nirtorch.load`` with Norse's own node mapping) simulates the
exported elite (``--fold-r``) and acts like the SPN to float32 rounding.

What of the path is ours: the file (``python -m spn_torchrl.export --fold-r``) and, below, :func:`norse_model`'s
one mapping ``nir.LI -> norse.torch.LIBoxCell`` (Norse 1.1 drops LI) and :func:`norse_actions`' loop that reads the
graph's metadata (zero state per observation, ``time_steps`` steps, max over time, argmax or clip). Reading the file
(``nir.read``), the graph's executor (nirtorch), Linear and LIF (``LIFBoxCell``) and every neuron update are theirs.
"""

from __future__ import annotations

import nir
import numpy as np
import pytest
import torch
from test_export import export, recorded_observations

from spn_torchrl.tools.elite import load_elite

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

norse = pytest.importorskip("norse.torch", reason="the test extra installs norse (--no-deps, see .ci/run)")
nirtorch = pytest.importorskip("nirtorch")
from norse.torch.utils.import_nir import _import_norse_module  # noqa: E402  (Norse's own NIR node mapping)


def norse_model(graph) -> torch.nn.Module:
    """The graph as a Norse module: Norse's mapping of every node, and Norse's LIBoxCell for nir.LI."""
    dt = float(graph.metadata["dt"])

    def model_map(node):
        if isinstance(node, nir.LI):
            params = norse.LIBoxParameters(
                tau_mem_inv=torch.as_tensor(1 / node.tau, dtype=torch.float32),
                v_leak=torch.as_tensor(node.v_leak, dtype=torch.float32),
            )
            return norse.LIBoxCell(params, dt=dt)
        return _import_norse_module(node, dt=dt)

    return nirtorch.load(graph, model_map)


def norse_actions(graph, observations: torch.Tensor) -> torch.Tensor:
    """Each observation from zero state for ``time_steps`` Norse steps; the max over time of the output, then the
    graph's action rule."""
    model, state, readout = norse_model(graph), None, None
    with torch.no_grad():
        for _ in range(int(graph.metadata["time_steps"])):
            out, state = model(observations, state)
            readout = out if readout is None else torch.maximum(readout, out)
    if graph.metadata["action"] == "argmax":
        return readout.argmax(-1)
    low, high = (torch.as_tensor(graph.metadata[k]) for k in ("action_low", "action_high"))
    return torch.clamp(readout, low, high)


@pytest.mark.parametrize("run", ["cartpole_run", "halfcheetah_run"])
def test_norse_simulates_the_exported_elite_like_the_spn(run, request, tmp_path):
    run_dir = request.getfixturevalue(run)
    out = tmp_path / "elite.nir"
    done = export(run_dir, out, "--fold-r")
    assert done.returncode == 0, done.stderr
    assert export(run_dir, tmp_path / "plain.nir").returncode == 0
    graph, plain = nir.read(out), nir.read(tmp_path / "plain.nir")
    assert all(np.all(graph.nodes[n].r == 1) for n in ("lif", "li")) and graph.metadata["r_folded"]
    for linear, neurons in (("linear_1", "lif"), ("linear_2", "li")):  # r = 4 is a power of two: folding is exact
        r = plain.nodes[neurons].r[:, None]
        assert np.array_equal(graph.nodes[linear].weight, (plain.nodes[linear].weight * r).astype(np.float32))
    # Norse 1.1 alone drops nir.LI without a word (Linear then feeds Output): the gap our one mapping fills
    assert "li" not in dict(norse.from_nir(graph, dt=graph.metadata["dt"]).named_children())
    model = norse_model(graph)
    assert isinstance(model.get_submodule("li"), norse.LIBoxCell)
    elite = load_elite(run_dir)
    observations = recorded_observations(elite, 1000)
    elite.spn.set_genomes(elite.genome[None].expand(len(observations), -1))
    expected, _ = elite.spn(observations)
    actions = norse_actions(graph, observations)
    diff = (actions.double() - expected.double()).abs()
    print(f"{run}: {len(observations)} observations, max |a_norse - a_ours| = {diff.max().item():.3g}, "
          f"{(diff == 0).double().mean().item():.4f} of the action components bit for bit")  # fmt: skip
    if graph.metadata["action"] == "argmax":
        assert torch.equal(actions, expected)
    else:  # Norse's v + dt/tau ((v_leak - v) + I) rounds apart from the SPN's 0.75 v + I in the last bit
        torch.testing.assert_close(actions, expected, rtol=0, atol=1e-6)
