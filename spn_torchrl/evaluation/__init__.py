"""Population evaluation: genomes in, one episode per genome out (returns, env steps, hidden spikes).

:mod:`~spn_torchrl.evaluation.rollout` runs a genome set on one batched env; :mod:`~spn_torchrl.evaluation.shards`
cuts it into shards for workers that each hold an env, in processes on this machine
(:mod:`~spn_torchrl.evaluation.processes`) or on Ray actors (:mod:`~spn_torchrl.evaluation.ray`).
:func:`make_evaluator` builds the one a config names.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Callable

from spn_torchrl.config import EVOLUTION, LocalEvaluatorConfig, RayEvaluatorConfig, RunConfig
from spn_torchrl.envs import TaskSpec, make_batched_env
from spn_torchrl.errors import require
from spn_torchrl.evaluation.processes import CALL_TIMEOUT_S, ProcessEvaluator, spawn_blocked_by
from spn_torchrl.evaluation.rollout import Evaluator, PopulationEvaluator
from spn_torchrl.snn.policies import PopulationSPN

log = logging.getLogger("spn_torchrl")


def local_processes(evaluator: LocalEvaluatorConfig, threads: int, slots: int, device: str = "cpu") -> int:
    """Worker processes of the local evaluator: ``evaluator.processes``, else the cores this process may use
    divided by the physics threads of each env (at most one per slot); one where a device steps every slot."""
    if evaluator.processes is not None:
        return min(evaluator.processes, slots)
    if device != "cpu":
        return 1
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    return max(1, min(cores // threads, slots))


def local_evaluator(cfg: RunConfig, spec: TaskSpec, spn: PopulationSPN, runs: int = 1) -> Evaluator:
    """The GA's or EC's evaluation slots of ``runs`` runs in lockstep on this machine, in :func:`local_processes`
    processes."""
    algo, evaluator = cfg.algo, cfg.evaluator
    assert isinstance(algo, EVOLUTION) and isinstance(evaluator, LocalEvaluatorConfig)
    slots = runs * algo.evaluation_slots
    return machine_evaluator(
        spn,
        spec.env_id,
        slots,
        cfg.env.backend,
        cfg.env.threads,
        spec.max_episode_steps,
        local_processes(evaluator, cfg.env.threads, slots, cfg.env.device),
        evaluator.start_timeout_s,
        evaluator.call_timeout_s,
        cfg.env.device,
    )


def machine_evaluator(
    spn: PopulationSPN,
    env_id: str,
    slots: int,
    backend: str,
    threads: int,
    max_episode_steps: int,
    processes: int = 1,
    start_timeout_s: float = 300.0,
    call_timeout_s: float | None = CALL_TIMEOUT_S,
    device: str = "cpu",
) -> Evaluator:
    """``slots`` copies of a task on this machine: one batched env in this process, or, with ``processes``
    > 1, one shard of them in each worker process (:mod:`spn_torchrl.evaluation.processes`), each call within
    ``call_timeout_s`` (None: no limit)."""
    if processes > 1:
        blocker = spawn_blocked_by()
        if blocker is None:
            return ProcessEvaluator(
                spn, env_id, slots, backend, threads, max_episode_steps, processes, start_timeout_s, call_timeout_s
            )
        log.warning(
            "evaluator.processes=%d: %s; evaluating in this process (same episodes, one core)", processes, blocker
        )
    env = make_batched_env(env_id, slots, backend=backend, threads=threads, device=device)
    return PopulationEvaluator(env, spn, max_episode_steps)


def ray_evaluator(cfg: RunConfig, spec: TaskSpec, spn: PopulationSPN) -> Evaluator:
    """The population sharded across Ray actors (:mod:`spn_torchrl.evaluation.ray`); needs the ``ray`` extra."""
    require("ray", "ray")
    from spn_torchrl.evaluation.ray import make_ray_evaluator  # Ray is an optional extra, imported only when used

    return make_ray_evaluator(cfg, spec, spn)


EVALUATORS: dict[type, Callable[[RunConfig, TaskSpec, PopulationSPN], Evaluator]] = {
    LocalEvaluatorConfig: local_evaluator,
    RayEvaluatorConfig: ray_evaluator,
}


def make_evaluator(cfg: RunConfig, spec: TaskSpec, spn: PopulationSPN) -> Evaluator:
    """The evaluator that ``cfg.evaluator`` (a local or a Ray config) describes."""
    return EVALUATORS[type(cfg.evaluator)](cfg, spec, spn)
