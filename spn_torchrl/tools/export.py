"""Export an evolved SPN: ``python -m spn_torchrl.export RUN_DIR --format nir OUT [--generation G]``.

The elite becomes a NIR graph (https://neuroir.org, the ``nir`` extra):
``input [n] -> linear_1 (W1*X1) -> lif [h] -> linear_2 (W2*X2) -> li [m] -> output``, no bias; the weights are
the fixed Kaiming weights with the elite's mask applied (absent synapses are zeros).

NIR's neurons are continuous-time (``tau dv/dt = (v_leak - v) + r I``); the paper's are discrete-time
(``v = g v + I``, g = decay = 0.75). The mapping: one simulation step lasts ``dt`` (stored in the graph's
metadata, 1 ms), and forward Euler, written ``v[t] = (1 - dt/tau) v[t-1] + (dt/tau) r I[t]``, equals the paper's
update when ``dt/tau = 1 - g`` and ``(dt/tau) r = 1``: ``tau = dt / (1 - g)`` = 4 ms and ``r = 1 / (1 - g)`` = 4,
``v_leak = 0``. (Both coefficients, 0.75 and 1, are exact in binary, so a simulator that computes them first
reproduces the project's floats exactly; ``v + (dt/tau)(r I - v)`` is the same in real arithmetic. The neuron
parameters are stored in float64 so that ``dt / tau`` is exactly ``1 - decay``.)

LIF: ``v_threshold = 0.5`` with a strict comparison (spike when ``v > 0.5``), ``v_reset = 0``. The paper applies
the reset of a spike at the next step (``v = g v (1 - s_prev) + I``); resetting to zero right after the spike,
as NIR's LIF does, gives the same spikes and potentials. Within one simulation step the graph is evaluated in
topological order (the LI layer sees the hidden spikes of the same step; no synaptic delay).

A run with ``normalize_observations=true`` normalises what the SPN sees with the running statistics its elite
was re-evaluated with: the graph then starts ``input -> obs_shift -> obs_scale -> linear_1``, an ``Affine``
(identity weight, bias ``-mean``) and a ``Scale`` (``inv_std``), float32, which compute the SPN's
``(x - mean) * inv_std`` bit for bit (``metadata["observation_normalization"]``).

What NIR does not express, stored in the graph's metadata: every environment step starts from zero state, the
observation is presented as a constant input for ``time_steps`` (T' = 4) simulation steps, and the readout is
the max over those T' steps of the LI potentials (``readout = "max_over_time"``), then ``argmax`` (discrete
actions) or clipping to ``action_low``/``action_high`` (continuous).

``--fold-r`` writes the equivalent graph with ``r = 1`` and each Linear's weight scaled by the ``r`` of the neurons
it feeds (``dt/tau * r * (W x) = dt/tau * ((r W) x)``), which consumers that ignore ``r`` (Norse 1.1, Sinabs) read
correctly. It is an option, not the default: the default's weights are the elite's masked weights themselves.
With decay 0.75, r = 4 is a power of two, so the folded weights are exact and ``W = (r W) / r``; with other
decays the folded weights are rounded to float32.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

from spn_torchrl.checkpoint import CHECKPOINT_NAME
from spn_torchrl.errors import SpnError, require
from spn_torchrl.lifecycle import COMMIT_NAME, LOCK_NAME, PROGRESS_NAME, RECORD_DIR
from spn_torchrl.records import run_file_error
from spn_torchrl.tools.elite import Elite, load_elite

DT = 1e-3  # seconds per simulation step (any positive value works: tau scales with it)
FORMATS = ("nir",)


def nir_parameters(decay: float, dt: float = DT) -> tuple[float, float]:
    """(tau, r) of NIR's LIF/LI whose forward-Euler step of length ``dt`` is ``v = decay * v + I``."""
    if not 0 <= decay < 1:
        raise SpnError(f"NIR export needs a decay in [0, 1) (a leaky neuron), got {decay}")
    return dt / (1.0 - decay), 1.0 / (1.0 - decay)


def to_nir(elite: Elite, dt: float = DT, fold_r: bool = False):
    """The elite SPN as a ``nir.NIRGraph`` (see the module docstring for the mapping); ``fold_r``: r = 1 and the
    weights scaled by r."""
    nir = require("nir", "nir")
    snn, spec = elite.cfg.algo.snn, elite.spec
    tau, r = nir_parameters(snn.decay, dt)
    scale = r if fold_r else 1.0
    w1, w2 = ((w.detach().double() * scale).numpy().astype(np.float32) for w in elite.weights)
    h, m = w1.shape[0], w2.shape[0]
    r = 1.0 if fold_r else r

    def full(size: int, value: float) -> np.ndarray:  # float64: dt / tau is then exactly 1 - decay
        return np.full(size, value, dtype=np.float64)

    metadata = {
        "producer": "spn_torchrl",
        "env_id": spec.env_id,
        "generation": elite.generation,
        "run_name": str(elite.state.get("run_name", "")),
        "dt": dt,
        "time_steps": int(snn.time_steps),
        "decay": float(snn.decay),
        "r_folded": bool(fold_r),
        "integration": "forward Euler: v[t] = (1 - dt/tau) * v[t-1] + (dt/tau) * r * I[t]",
        "threshold": "strict: spike when v > v_threshold; reset to v_reset right after the spike",
        "state": "zero at the start of every environment step",
        "input": "the observation, constant for time_steps simulation steps",
        "readout": "max_over_time",
        "action": "argmax" if spec.discrete else "clip",
        "action_low": np.zeros(0, np.float32) if spec.discrete else spec.action_low.numpy(),
        "action_high": np.zeros(0, np.float32) if spec.discrete else spec.action_high.numpy(),
    }
    nodes = {
        "input": nir.Input(input_type={"input": np.array([spec.n_obs])}),
        "linear_1": nir.Linear(weight=w1),
        "lif": nir.LIF(
            tau=full(h, tau),
            r=full(h, r),
            v_leak=full(h, 0.0),
            v_threshold=full(h, snn.v_threshold),
            v_reset=full(h, 0.0),
        ),
        "linear_2": nir.Linear(weight=w2),
        "li": nir.LI(tau=full(m, tau), r=full(m, r), v_leak=full(m, 0.0)),
        "output": nir.Output(output_type={"output": np.array([m])}),
    }
    edges = [("input", "linear_1"), ("linear_1", "lif"), ("lif", "linear_2"), ("linear_2", "li"), ("li", "output")]
    metadata["observation_normalization"] = "none"
    if elite.obs_norm is not None:
        mean, inv_std = (t[0].detach().numpy().astype(np.float32) for t in elite.obs_norm)
        nodes["obs_shift"] = nir.Affine(weight=np.eye(spec.n_obs, dtype=np.float32), bias=-mean)
        nodes["obs_scale"] = nir.Scale(scale=inv_std)
        edges[0:1] = [("input", "obs_shift"), ("obs_shift", "obs_scale"), ("obs_scale", "linear_1")]
        metadata["observation_normalization"] = "(x - mean) * inv_std: obs_shift (bias -mean), obs_scale (inv_std)"
    return nir.NIRGraph(nodes=nodes, edges=edges, metadata=metadata)


def export(
    run_dir: str | Path, out: str | Path, fmt: str = "nir", generation: int | None = None, fold_r: bool = False
) -> Path:
    """Write the elite of ``generation`` (default: the last) of the run in ``run_dir`` to ``out``."""
    if fmt not in FORMATS:
        raise SpnError(f"--format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    nir = require("nir", "nir")
    elite = load_elite(run_dir, generation)
    graph = to_nir(elite, fold_r=fold_r)
    out = Path(out)
    refuse_run_file(Path(run_dir), out)
    try:
        out.parent.mkdir(parents=True, exist_ok=True)
        nir.write(out, graph)
    except OSError as err:  # a directory at ``out``, a read-only or full disk: one sentence naming the path
        raise run_file_error(out, err) from None
    return out


# what a run writes in its directory (lifecycle, checkpoint, Hydra's log, the loggers): never an export's target
RUN_FILES = (CHECKPOINT_NAME, PROGRESS_NAME, COMMIT_NAME, LOCK_NAME, "train.log")
RUN_DIRS = (RECORD_DIR, "logs", "wandb")


def refuse_run_file(run_dir: Path, out: Path) -> None:
    """SpnError where ``out`` is one of the files the run in ``run_dir`` wrote (its checkpoint, its record)."""
    try:
        inside = out.resolve().relative_to(run_dir.resolve())
    except ValueError:
        return
    if str(inside) in RUN_FILES or (inside.parts and inside.parts[0] in RUN_DIRS):
        raise SpnError(f"{out} is a file of the run in {run_dir}: write the export to another path")


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m spn_torchrl.export", description="Export a run's elite SPN.")
    parser.add_argument("run_dir", type=Path, help="a GA run directory (holds checkpoint.pt)")
    parser.add_argument("out", type=Path, help="the file to write (e.g. elite.nir)")
    parser.add_argument("--format", default="nir", choices=FORMATS, help="output format (default nir)")
    parser.add_argument("--generation", type=int, default=None, help="whose elite (1-based; default: the last)")
    parser.add_argument(
        "--fold-r", action="store_true", help="r = 1, weights scaled by r: for consumers that ignore r (Norse, Sinabs)"
    )
    args = parser.parse_args(argv)
    try:
        path = export(args.run_dir, args.out, args.format, args.generation, args.fold_r)
    except SpnError as err:
        sys.exit(f"error: {err}")
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
