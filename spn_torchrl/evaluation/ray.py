"""Population evaluation on Ray: ``evaluator=ray``.

The population is cut into contiguous shards, one per actor (:mod:`spn_torchrl.evaluation.shards`). Each actor builds its
batched env and SPN once (the fixed weights reach it once, through the object store) and runs its shard, so that
every individual gets the same episode as in the local evaluator. Per call only the genomes go out (connection
genomes as packed mask bits) and three numbers per individual come back.

Only this module imports Ray, and only :func:`spn_torchrl.evaluation.ray_evaluator` imports this module.
"""

from __future__ import annotations

import contextlib
import logging
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import ray
import torch

from spn_torchrl.config import RayEvaluatorConfig, RunConfig
from spn_torchrl.envs import TaskSpec
from spn_torchrl.errors import EvaluatorError
from spn_torchrl.evaluation.rollout import Episodes
from spn_torchrl.evaluation.shards import ShardWorker, merge, shard_bounds, shard_requests, without_genomes
from spn_torchrl.snn.observations import Norm
from spn_torchrl.snn.policies import PopulationSPN

log = logging.getLogger("spn_torchrl")


ShardActor = ray.remote(ShardWorker)


class RayEvaluator:
    """The :class:`~spn_torchrl.evaluation.rollout.Evaluator` over Ray actors; counts the payload bytes it moves."""

    def __init__(
        self, actors: list, capacity: int, spn: PopulationSPN, call_timeout_s: float | None, owns_ray: bool
    ) -> None:
        self.actors = actors
        self.capacity = capacity
        self.spn = spn
        self.call_timeout_s = call_timeout_s
        self.owns_ray = owns_ray
        self.bytes_setup = 0  # fixed weights sent once at start
        self.bytes_sent = 0  # genomes and seeds, every call
        self.bytes_received = 0  # returns, steps, spikes, every call

    def __call__(
        self, genomes: torch.Tensor, seeds: int | np.ndarray, norm: Norm | None = None, runs: np.ndarray | None = None
    ) -> Episodes:
        calls = []
        for index, start, stop, shard, shard_seeds, part, shard_runs in shard_requests(
            self.spn, genomes, seeds, len(self.actors), self.capacity, "Ray actors", norm, runs
        ):
            self.bytes_sent += shard.nbytes + shard_seeds.nbytes  # + an int64 seed per genome
            self.bytes_sent += 0 if part is None else sum(rows.nbytes for rows in part)
            remote = self.actors[index].evaluate.remote(shard, shard_seeds, part, shard_runs)
            calls.append((index, start, stop, remote))
        deadline = None if self.call_timeout_s is None else time.monotonic() + self.call_timeout_s
        return merge([self._collect(*call, deadline) for call in calls])

    def _collect(self, index: int, start: int, stop: int, ref, deadline: float | None):
        where = f"Ray actor {index} (individuals {start}..{stop - 1})"
        try:
            result = ray.get(ref, timeout=None if deadline is None else max(0.0, deadline - time.monotonic()))
        except ray.exceptions.GetTimeoutError:
            raise EvaluatorError(
                f"{where} did not answer within evaluator.call_timeout_s={self.call_timeout_s} s"
            ) from None
        except ray.exceptions.RayActorError as err:
            raise EvaluatorError(
                f"{where} died and could not be restarted (evaluator.max_restarts): {_first_line(err)}"
            ) from err
        except ray.exceptions.RayTaskError as err:
            raise EvaluatorError(f"{where} failed: {_first_line(err.cause or err)}") from err
        if any(len(part) != stop - start for part in result):
            raise EvaluatorError(f"{where} returned {len(result[0])} results for {stop - start} genomes")
        self.bytes_received += sum(part.nbytes for part in result)
        return result

    def close(self) -> None:
        for actor in self.actors:
            ray.kill(actor)
        self.actors = []
        if self.owns_ray and ray.is_initialized():
            ray.shutdown()
            self.owns_ray = False


def _first_line(err: BaseException) -> str:
    text = str(err).strip()
    return f"{type(err).__name__}: {text.splitlines()[0] if text else ''}"


def connect(evaluator: RayEvaluatorConfig) -> bool:
    """Join the cluster at ``evaluator.address`` or start a local one; True when this call started Ray."""
    if ray.is_initialized():
        return False
    # ship_code: Ray uploads this package for the job's workers (only possible when this process joins)
    runtime_env = {"py_modules": [str(Path(__file__).resolve().parent)]} if evaluator.ship_code else None
    with kept_signal_handlers():
        try:
            if evaluator.address is None:
                ray.init(num_cpus=evaluator.num_cpus, include_dashboard=False, runtime_env=runtime_env)
            else:
                ray.init(address=evaluator.address, runtime_env=runtime_env)
        except ConnectionError as err:
            raise EvaluatorError(
                f"could not reach the Ray cluster at evaluator.address={evaluator.address!r}: {err}"
            ) from None
    return True


@contextlib.contextmanager
def kept_signal_handlers() -> Iterator[None]:
    """SIGINT and SIGTERM keep this process's handlers through the body (in the main thread). ``ray.init`` sets
    its own: a Python SIGTERM handler that exits, and its core worker's C++ failure handler, which dumps a stack
    and aborts (rc 134) over Python's; setting ours again puts the run's handlers (a signalled run ends after its
    checkpoint, exit 128 + signal) back in front of both."""
    sigs = (signal.SIGINT, signal.SIGTERM)
    main = threading.current_thread() is threading.main_thread()
    previous = {sig: signal.getsignal(sig) for sig in sigs} if main else {}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            if handler is not None:  # None: a handler not set from Python, which Python cannot set again
                signal.signal(sig, handler)


def make_ray_evaluator(cfg: RunConfig, spec: TaskSpec, spn: PopulationSPN) -> RayEvaluator:
    """Start ``evaluator.num_actors`` shard actors (each with its env built) and wait until all are up."""
    ev = cfg.evaluator
    owns_ray = connect(ev)
    cpus = ray.cluster_resources().get("CPU", 0)
    if owns_ray and ev.address is None and ev.num_actors * ev.num_cpus_per_actor > cpus:
        ray.shutdown()
        raise EvaluatorError(
            f"evaluator.num_actors={ev.num_actors} x evaluator.num_cpus_per_actor={ev.num_cpus_per_actor} CPUs do not fit "
            f"in the local Ray cluster's {cpus:g} CPUs: lower one of them or set evaluator.num_cpus"
        )
    population = cfg.algo.evaluation_slots
    capacities = [stop - start for start, stop in shard_bounds(population, ev.num_actors)]
    options = {"num_cpus": ev.num_cpus_per_actor, "max_restarts": ev.max_restarts, "max_task_retries": ev.max_restarts}
    # the SPN (its fixed weights) goes to each actor once, inside the creation task, which Ray keeps for restarts
    bare = without_genomes(spn)
    actors = [
        ShardActor.options(**options).remote(
            bare, spec.env_id, size, cfg.env.backend, cfg.env.threads, spec.max_episode_steps
        )
        for size in capacities
    ]
    evaluator = RayEvaluator(actors, population, spn, ev.call_timeout_s, owns_ray)
    evaluator.bytes_setup = len(actors) * (spn.w1.nbytes + spn.w2.nbytes)
    try:
        started, waiting = ray.wait(
            [a.ready.remote() for a in actors], num_returns=len(actors), timeout=ev.start_timeout_s
        )
        if waiting:
            raise EvaluatorError(
                f"{len(waiting)} of {len(actors)} Ray actors did not start within evaluator.start_timeout_s="
                f"{ev.start_timeout_s} s (the cluster has {cpus:g} CPUs, the actors ask for {len(actors)} x "
                f"evaluator.num_cpus_per_actor={ev.num_cpus_per_actor}): lower evaluator.num_actors or "
                "evaluator.num_cpus_per_actor, or grow the cluster"
            )
        try:
            ray.get(started)
        except ray.exceptions.RayError as err:
            cause = err.cause if isinstance(err, ray.exceptions.RayTaskError) and err.cause else err
            raise EvaluatorError(f"a Ray actor failed to build its env: {_first_line(cause)}") from err
    except BaseException:
        evaluator.close()
        raise
    log.info("Ray evaluator: %d actors holding %s individuals", len(actors), capacities)
    return evaluator
