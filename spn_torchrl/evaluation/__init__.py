"""Population evaluation: genomes in, one episode per genome out (returns, env steps, hidden spikes).

:mod:`~spn_torchrl.evaluation.rollout` runs a genome set on one batched env; :mod:`~spn_torchrl.evaluation.shards`
cuts it into shards for workers that each hold an env, in processes on this machine
(:mod:`~spn_torchrl.evaluation.processes`) or on Ray actors (:mod:`~spn_torchrl.evaluation.ray`).
:func:`make_evaluator` builds the one a config names.
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from omegaconf import DictConfig

from spn_torchrl.envs import TaskSpec, make_batched_env
from spn_torchrl.errors import ConfigError, require
from spn_torchrl.evaluation.processes import CALL_TIMEOUT_S, ProcessEvaluator, spawn_blocked_by
from spn_torchrl.evaluation.rollout import Evaluator, PopulationEvaluator, evaluation_slots
from spn_torchrl.snn.policies import PopulationSPN

log = logging.getLogger("spn_torchrl")


def local_evaluator(cfg: DictConfig, spec: TaskSpec, spn: PopulationSPN) -> Evaluator:
    """The :func:`evaluation_slots` copies on this machine, in ``env.processes`` processes."""
    return machine_evaluator(
        spn,
        spec.env_id,
        evaluation_slots(cfg.algo),
        cfg.env.backend,
        cfg.env.num_workers,
        spec.max_episode_steps,
        cfg.env.processes,
        cfg.evaluator.start_timeout_s,
        cfg.evaluator.get("call_timeout_s", CALL_TIMEOUT_S),
    )


def machine_evaluator(
    spn: PopulationSPN,
    env_id: str,
    slots: int,
    backend: str,
    num_workers: int,
    max_episode_steps: int,
    processes: int = 1,
    start_timeout_s: float = 300.0,
    call_timeout_s: float | None = CALL_TIMEOUT_S,
) -> Evaluator:
    """``slots`` copies of a task on this machine: one batched env in this process, or, with ``processes``
    > 1, one shard of them in each worker process (spn_torchrl/process_evaluator.py), each call within
    ``call_timeout_s``."""
    if processes > 1:
        blocker = spawn_blocked_by()
        if blocker is None:
            return ProcessEvaluator(
                spn, env_id, slots, backend, num_workers, max_episode_steps, processes, start_timeout_s, call_timeout_s
            )
        log.warning("env.processes=%d: %s; evaluating in this process (same episodes, one core)", processes, blocker)
    return PopulationEvaluator(
        make_batched_env(env_id, slots, backend=backend, num_workers=num_workers), spn, max_episode_steps
    )


def ray_evaluator(cfg: DictConfig, spec: TaskSpec, spn: PopulationSPN) -> Evaluator:
    """The population sharded across Ray actors (spn_torchrl/ray_evaluator.py); needs the ``ray`` extra."""
    require("ray", "ray")
    from spn_torchrl.evaluation.ray import make_ray_evaluator

    return make_ray_evaluator(cfg, spec, spn)


EVALUATORS: dict[str, Callable[[DictConfig, TaskSpec, PopulationSPN], Evaluator]] = {
    "local": local_evaluator,
    "ray": ray_evaluator,
}


def make_evaluator(cfg: DictConfig, spec: TaskSpec, spn: PopulationSPN) -> Evaluator:
    """The evaluator named by ``evaluator.name``."""
    name = cfg.evaluator.name
    if name not in EVALUATORS:
        raise ConfigError(f"evaluator.name must be one of {sorted(EVALUATORS)}, got {name!r}")
    return EVALUATORS[name](cfg, spec, spn)
