"""The one entry point: ``run(cfg)`` validates a composed config and runs the chosen method."""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig

from spn_torchrl.config import validate
from spn_torchrl.records import sweep_name

log = logging.getLogger("spn_torchrl")


def hydra_run_dir() -> Path | None:
    """Hydra's output directory for this job, or None outside a Hydra app."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return None
    return Path(HydraConfig.get().runtime.output_dir)


def run_name(cfg: DictConfig) -> str:
    """``run_name`` if set; in a Hydra sweep ``{env}__{algo}__{seed}`` (the sweep names the group); else
    ``{env}__{algo}__{seed}__{time}``, so that repeated single runs stay apart."""
    if cfg.run_name:
        return cfg.run_name
    name = f"{cfg.env.name}__{cfg.algo.name}__{cfg.seed}"
    return name if sweep_name() is not None else f"{name}__{int(time.time())}"


def run(cfg: DictConfig, run_dir: str | Path | None = None) -> dict[str, Any]:
    """Validate ``cfg`` and run its algorithm in ``run_dir`` (default: Hydra's output directory)."""
    validate(cfg)
    out = Path(run_dir) if run_dir is not None else hydra_run_dir()
    if out is None:
        raise ValueError("run(cfg) outside a Hydra app needs run_dir")
    out.mkdir(parents=True, exist_ok=True)
    torch.set_num_threads(cfg.torch_threads)
    kind = cfg.algo.kind
    if kind == "ga":
        from spn_torchrl.training.evolve import evolve

        return evolve(cfg, out, run_name(cfg))
    if kind == "ppo":
        from spn_torchrl.training.ppo import train_ppo

        return train_ppo(cfg, out, run_name(cfg))
    raise AssertionError(f"validate() let algo.kind={kind!r} through")
