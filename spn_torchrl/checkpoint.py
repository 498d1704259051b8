"""Checkpoints: written atomically after every generation or iteration, loaded with ``weights_only=True`` and
checked against their format's layout (entries, types and shapes) before any run or tool reads them."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, NamedTuple

import torch

from spn_torchrl.errors import CheckpointError
from spn_torchrl.records import save_torch_atomic

CHECKPOINT_NAME = "checkpoint.pt"
# /3: episode seeds by role and index, the run's config as a dict and its rows in the state (/2: the pending
# re-evaluation is part of the state); tools still read /2 elites
GA_FORMAT = "spn_torchrl.ga/3"
EC_FORMAT = "spn_torchrl.ec/1"  # a GA/3 state with EC's p and Adam state ("p", "adam") in it
GA_FORMATS_READABLE = ("spn_torchrl.ga/2", GA_FORMAT, EC_FORMAT)  # whose elites the tools read
PPO_FORMAT = "spn_torchrl.ppo/2"  # /2: the run's config as a dict and its rows in the state


class Tensor(NamedTuple):
    """A layout entry: a tensor with ``ndim`` dimensions (and ``dtype``, where one is required)."""

    ndim: int
    dtype: torch.dtype | None = None


Entry = type | tuple[type, ...] | Tensor
NUMBER = (int, float)
_RUN: dict[str, Entry] = {"meta": dict, "config": dict, "rows": list, "run_name": str, "wandb_id": (str, type(None))}
_GA: dict[str, Entry] = {
    **_RUN,
    "generation": int,
    "population": Tensor(2),
    "pending": (dict, type(None)),
    "rng": Tensor(1, torch.uint8),
    "w1": Tensor(2),
    "w2": Tensor(2),
    "elites": Tensor(2),
    "total_env_steps": int,
    "wall_time_s": NUMBER,
}
LAYOUTS: dict[str, dict[str, Entry]] = {  # the entries each format's state holds
    "spn_torchrl.ga/2": {"meta": dict, "config": dict, "w1": Tensor(2), "w2": Tensor(2), "elites": Tensor(2)},
    GA_FORMAT: _GA,
    EC_FORMAT: {**_GA, "p": Tensor(1), "adam": dict},
    PPO_FORMAT: {
        **_RUN,
        "iteration": int,
        "actor": dict,
        "critic": dict,
        "optim": dict,
        "counts": dict,
        "wall_time_s": NUMBER,
        "torch_rng": Tensor(1, torch.uint8),
    },
}
_PENDING: dict[str, Entry] = {
    "generation": int,
    "population": Tensor(2),
    "fitness": Tensor(1),
    "steps": int,
    "candidates": Tensor(1),
}
_META: dict[str, Entry] = {"format": str, "env_id": str}
_ADAM: dict[str, Entry] = {"m": Tensor(1), "v": Tensor(1), "t": int}
_STATS: dict[str, Entry] = {"count": int, "mean": Tensor(1), "summed_variance": Tensor(1), "std": Tensor(1)}


def save(state: Mapping[str, Any], run_dir: Path) -> Path:
    """Write ``run_dir/checkpoint.pt`` atomically."""
    path = Path(run_dir) / CHECKPOINT_NAME
    save_torch_atomic(dict(state), path)
    return path


def load(path: Path, expected: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Read a checkpoint (a file or a run directory), check that its ``meta`` matches ``expected`` and that a
    known format's state has that format's layout (:data:`LAYOUTS`)."""
    path = Path(path)
    if path.is_dir():
        path = path / CHECKPOINT_NAME
    if not path.exists():
        raise CheckpointError(f"no checkpoint at {path}")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as err:  # torch raises many types for a truncated or foreign file
        raise CheckpointError(
            f"{path} is not a readable spn_torchrl checkpoint (corrupt or foreign file: {type(err).__name__})"
        ) from None
    if not isinstance(state, dict) or not isinstance(state.get("meta"), dict):
        raise CheckpointError(f"{path} is not a spn_torchrl checkpoint (no 'meta' entry)")
    for key, want in (expected or {}).items():
        have = state["meta"].get(key)
        if have != want:
            raise CheckpointError(
                f"{path} was written for {key}={have!r}, but this run has {key}={want!r}: "
                "use a new run directory or the matching config"
            )
    fmt = state["meta"].get("format")
    if fmt in LAYOUTS:
        problem = layout_problem(state, fmt)
        if problem is not None:
            raise damaged(path, fmt, problem)
    return state


def damaged(path: Path, fmt: Any, problem: str) -> CheckpointError:
    """The one sentence for a checkpoint that loads but does not hold what its format does."""
    return CheckpointError(
        f"{path} is a damaged {fmt} checkpoint ({problem}): restore it from a copy, or use a new run directory"
    )


def layout_problem(state: Mapping[str, Any], fmt: str) -> str | None:
    """What in ``state`` departs from format ``fmt``'s layout and shapes (None: nothing)."""
    problem = _entries_problem(state, LAYOUTS[fmt], "") or _entries_problem(state["meta"], _META, "meta.")
    if problem is not None or fmt == PPO_FORMAT:
        return problem or _rng_problem(state["torch_rng"], "torch_rng")
    return _genome_problem(state, fmt)


def _genome_problem(state: Mapping[str, Any], fmt: str) -> str | None:
    """The GA and EC entries within: w1 [h, n] and w2 [m, h], every genome D = h n + m h genes."""
    w1, w2 = state["w1"], state["w2"]
    if w1.shape[0] != w2.shape[1]:
        return f"'w1' {tuple(w1.shape)} and 'w2' {tuple(w2.shape)} are not [h, n] and [m, h]"
    shaped = {"elites": (state["elites"], -1)}
    if fmt != "spn_torchrl.ga/2":
        pending, ec, normalised = state["pending"], fmt == EC_FORMAT, "obs_stats" in state
        problem = (
            _rng_problem(state["rng"], "rng")
            or _entries_problem(pending or {}, _PENDING if pending else {}, "pending.")
            or _entries_problem(state.get("adam", {}), _ADAM if ec else {}, "adam.")
            or _entries_problem(state, {"obs_stats": dict, "elite_norms": Tensor(3)} if normalised else {}, "")
            or _entries_problem(state.get("obs_stats") or {}, _STATS if normalised else {}, "obs_stats.")
            or _norms_problem(state)
            or next(
                (f"'rows' holds a {type(r).__name__}, not a row" for r in state["rows"] if not isinstance(r, dict)),
                None,
            )
        )
        if problem is not None:
            return problem
        shaped["population"] = (state["population"], -1)
        if pending:
            shaped["pending.population"] = (pending["population"], -1)
        if ec:
            shaped.update({"p": (state["p"], 0), "adam.m": (state["adam"]["m"], 0), "adam.v": (state["adam"]["v"], 0)})
    genes = w1.numel() + w2.numel()
    for key, (value, dim) in shaped.items():
        if value.shape[dim] != genes:
            return f"'{key}' has shape {tuple(value.shape)}, not {genes} genes (those of 'w1' and 'w2')"
    return None


def _norms_problem(state: Mapping[str, Any]) -> str | None:
    """Each elite's (mean, inv_std) where the run normalised observations: [2, G, n] beside G elites."""
    norms, count = state.get("elite_norms"), state["elites"].shape[0]
    if norms is None or not isinstance(norms, torch.Tensor) or tuple(norms.shape[:2]) == (2, count):
        return None
    return f"'elite_norms' has shape {tuple(norms.shape)}, not [2, {count}, n] beside {count} elites"


def _rng_problem(value: torch.Tensor, key: str) -> str | None:
    try:
        torch.Generator().set_state(value)
    except (RuntimeError, TypeError):
        return f"'{key}' is not a random generator's state"
    return None


def _entries_problem(state: Mapping[str, Any], layout: Mapping[str, Entry], prefix: str) -> str | None:
    """The first entry of ``layout`` that ``state`` lacks or holds with another type or dimensionality."""
    for key, entry in layout.items():
        if key not in state:
            return f"no '{prefix}{key}' entry"
        value = state[key]
        if isinstance(entry, Tensor):
            if not isinstance(value, torch.Tensor) or value.ndim != entry.ndim:
                have = f"shape {tuple(value.shape)}" if isinstance(value, torch.Tensor) else type(value).__name__
                return f"'{prefix}{key}' is a {have}, not a {entry.ndim}-dimensional tensor"
            if entry.dtype is not None and value.dtype != entry.dtype:
                return f"'{prefix}{key}' holds {value.dtype}, not {entry.dtype}"
        elif not isinstance(value, entry) or (isinstance(value, bool) and entry in (int, NUMBER)):
            return f"'{prefix}{key}' is a {type(value).__name__}"
    return None
