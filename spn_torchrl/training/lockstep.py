"""GA or EC runs in lockstep: R runs of one task and method, differing in seed, evolved in one process, every
rollout one batch of R x (N + k x E) slots (``lockstep=[seeds]``).

Each run is a whole run of its own: its directory ``{lockstep dir}/{env}__{algo}__{seed}`` holds its lock, its
record (``.hydra/``), ``progress.csv``, checkpoint, ``COMMIT`` and logger (its own W&B run), under the run
contract of :mod:`spn_torchrl.lifecycle`, and its config is the config of a separate run of its seed
(``lockstep`` null). Each run keeps its fixed weights, generator, method state (EC's p and Adam state) and
observation statistics; the SPN holds every run's fixed weights and each genome uses its run's
(:class:`~spn_torchrl.snn.policies.PopulationSPN`); each slot gets its run's normalisation and each episode its
run's env seed (:mod:`spn_torchrl.seeds`). So on the CPU backends a run's rows are those of the separate run, bit
for bit, all but wall time and speed, and a run may be resumed, extended or stopped in lockstep or alone. Runs
that stand at different generations (one extended alone) share rollouts until each reaches its budget. A
non-finite value in one run stops the batch, every run at its last checkpoint.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
from pathlib import Path
from typing import Any

import numpy as np
import torch

from spn_torchrl.config import RunConfig
from spn_torchrl.envs import task_spec
from spn_torchrl.evaluation import local_evaluator
from spn_torchrl.lifecycle import deferred_signals, open_run, run_lock
from spn_torchrl.records import run_file_error, sweep_name
from spn_torchrl.snn.policies import spn_from_config
from spn_torchrl.training.evolve import Generations, run_meta, start_state

log = logging.getLogger("spn_torchrl")


def run_configs(cfg: RunConfig, group: str) -> list[RunConfig]:
    """The config of each run of ``cfg.lockstep``: a separate run's of its seed, W&B runs grouped (``logger.group``,
    else the sweep's or the lockstep directory's name ``group``)."""
    logger = dataclasses.replace(cfg.logger, group=cfg.logger.group or sweep_name() or group)
    return [dataclasses.replace(cfg, seed=seed, lockstep=None, logger=logger) for seed in cfg.lockstep]


def run_dir_name(cfg: RunConfig) -> str:
    """A run's directory and name in its lockstep directory: ``{env}__{algo}__{seed}``, as a sweep's subdirectory
    (``{run_name}__{seed}`` where ``run_name`` is set)."""
    return f"{cfg.run_name or f'{cfg.env.name}__{cfg.algo.name}'}__{cfg.seed}"


def evolve_lockstep(cfg: RunConfig, out: Path) -> dict[int, dict[str, Any]]:
    """Run (or resume) the GA or EC runs of ``cfg.lockstep`` in lockstep under ``out``; returns each seed's last row."""
    spec = task_spec(cfg.env.id)
    configs = run_configs(cfg, out.name)
    with contextlib.ExitStack() as stack:
        loops: list[Generations] = []
        last: dict[int, dict[str, Any]] = {}
        for run_cfg in configs:
            name = run_dir_name(run_cfg)
            run_dir = out / name
            try:
                run_dir.mkdir(parents=True, exist_ok=True)
            except OSError as err:
                raise run_file_error(run_dir, err) from None
            stack.enter_context(run_lock(run_dir))
            run = stack.enter_context(
                open_run(run_cfg, run_dir, name, run_cfg.algo.kind, run_meta(run_cfg, spec), run_cfg.algo.generations)
            )
            state = start_state(run_cfg, spec, run)
            if state is None:
                last[run_cfg.seed] = run.rows[-1] if run.rows else {}
            else:
                loops.append(Generations(run_cfg, spec, run, state, label=f"seed {run_cfg.seed}: "))
        if loops:
            _lockstep(cfg, spec, loops)
            last.update({loop.cfg.seed: loop.row for loop in loops})
        return last


def _lockstep(cfg: RunConfig, spec: Any, loops: list[Generations]) -> None:
    """Every rollout of ``loops`` in one evaluator of R x (N + k x E) slots, each genome on its run's weights."""
    algo = cfg.algo
    spn = spn_from_config(
        algo.snn, algo.genome, spec, torch.stack([loop.w1 for loop in loops]), torch.stack([loop.w2 for loop in loops])
    )
    slots = len(loops) * algo.evaluation_slots
    evaluator = local_evaluator(cfg, spec, spn, len(loops))
    log.info("%d runs in lockstep (seeds %s): %d slots", len(loops), [loop.cfg.seed for loop in loops], slots)
    try:
        while asked := [(loop, request) for loop in loops if (request := loop.next_rollout()) is not None]:
            genomes = torch.cat([request[0] for _, request in asked])
            seeds = np.concatenate([request[1] for _, request in asked])
            runs = np.concatenate([np.full(len(request[1]), loops.index(loop)) for loop, request in asked])
            norms = [request[2] for _, request in asked]  # all None, or all set: the runs share one config
            norm = None if norms[0] is None else tuple(torch.cat(parts) for parts in zip(*norms))
            result = evaluator(genomes, seeds, norm, runs=runs)
            start = 0
            with deferred_signals():  # a signal stops the runs once each has saved this rollout
                for loop, request in asked:
                    stop = start + len(request[1])
                    loop.take(result.part(start, stop))
                    start = stop
    finally:
        evaluator.close()
