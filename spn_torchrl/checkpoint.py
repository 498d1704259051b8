"""Checkpoints: written atomically after every generation or iteration, loaded with ``weights_only=True``."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

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


def save(state: Mapping[str, Any], run_dir: Path) -> Path:
    """Write ``run_dir/checkpoint.pt`` atomically."""
    path = Path(run_dir) / CHECKPOINT_NAME
    save_torch_atomic(dict(state), path)
    return path


def load(path: Path, expected: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """Read a checkpoint (a file or a run directory) and check that its ``meta`` matches ``expected``."""
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
    if not isinstance(state, dict) or "meta" not in state:
        raise CheckpointError(f"{path} is not a spn_torchrl checkpoint (no 'meta' entry)")
    for key, want in (expected or {}).items():
        have = state["meta"].get(key)
        if have != want:
            raise CheckpointError(
                f"{path} was written for {key}={have!r}, but this run has {key}={want!r}: "
                "use a new run directory or the matching config"
            )
    return state
