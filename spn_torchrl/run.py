"""The one entry point: ``run(cfg)`` turns a composed config into typed objects, checks it, and runs the method."""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import torch
from omegaconf import DictConfig

from spn_torchrl import checkpoint
from spn_torchrl.config import EVOLUTION, RunConfig, to_run_config
from spn_torchrl.envs import check_backend, task_spec
from spn_torchrl.envs.mujoco_warp import torch_device
from spn_torchrl.errors import RunInterrupted, require
from spn_torchrl.lifecycle import resume_hint, run_lock, signals_interrupt
from spn_torchrl.records import run_file_error, sweep_name, wandb_mode
from spn_torchrl.training.evolve import evolve
from spn_torchrl.training.lockstep import evolve_lockstep
from spn_torchrl.training.ppo import train_ppo

log = logging.getLogger("spn_torchrl")


def hydra_run_dir() -> Path | None:
    """Hydra's output directory for this job, or None outside a Hydra app."""
    from hydra.core.hydra_config import HydraConfig

    if not HydraConfig.initialized():
        return None
    return Path(HydraConfig.get().runtime.output_dir)


def run_name(cfg: RunConfig) -> str:
    """``run_name`` if set; in a Hydra sweep ``{env}__{algo}__{seed}`` (the sweep names the group); else
    ``{env}__{algo}__{seed}__{time}``, so that repeated single runs stay apart."""
    if cfg.run_name:
        return cfg.run_name
    name = f"{cfg.env.name}__{cfg.algo.name}__{cfg.seed}"
    return name if sweep_name() is not None else f"{name}__{int(time.time())}"


def check(cfg: RunConfig) -> None:
    """What the dataclasses cannot check alone, before any env or worker starts: the task exists, the backend
    steps it, and a W&B logger can be online (an API key, a server that answers) or goes offline."""
    task_spec(cfg.env.id)
    check_backend(cfg.env.backend, cfg.env.id)
    if cfg.env.backend == "mujoco_warp":
        require("mujoco_warp", "gpu")
        torch_device(cfg.env.device)  # a CUDA device this machine has
    if cfg.logger.backend == "wandb":
        wandb_mode(cfg.logger.mode)


def run(cfg: DictConfig | RunConfig, run_dir: str | Path | None = None) -> dict[str, Any]:
    """Check ``cfg`` and run its algorithm in ``run_dir`` (default: Hydra's output directory); returns the last
    row (with ``lockstep``, each seed's, its runs in subdirectories of ``run_dir``). SIGINT and SIGTERM end it
    with :class:`RunInterrupted` after its last consistent checkpoint."""
    typed = cfg if isinstance(cfg, RunConfig) else to_run_config(cfg)
    check(typed)
    out = Path(run_dir) if run_dir is not None else hydra_run_dir()
    if out is None:
        raise ValueError("run(cfg) outside a Hydra app needs run_dir")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise run_file_error(out, err) from None
    torch.set_num_threads(typed.torch_threads)
    train = evolve if isinstance(typed.algo, EVOLUTION) else train_ppo
    try:
        with signals_interrupt(), run_lock(out):
            if typed.lockstep is not None:  # each run also holds its own directory's lock
                return evolve_lockstep(typed, out)
            return train(typed, out, run_name(typed))
    except RunInterrupted as err:
        name = checkpoint.CHECKPOINT_NAME
        if (out / name).exists() or (typed.lockstep is not None and any(out.glob(f"*/{name}"))):
            err.args = (f"{err.args[0]}; {out} holds a consistent checkpoint, resume with: {resume_hint(out)}",)
        else:
            hint = resume_hint(out, resume=False)
            err.args = (f"{err.args[0]} before the first checkpoint; {out} holds none, start again with: {hint}",)
        raise
