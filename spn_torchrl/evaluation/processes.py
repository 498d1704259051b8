"""Population evaluation in worker processes on this machine: ``env.processes`` > 1.

Each worker process holds one shard's batched env and SPN (:class:`~spn_torchrl.evaluation.shards.ShardWorker`, built
once) and runs its episodes to their end on its own. One shard's SPN and env bookkeeping run while the other
shards' physics runs, so no core waits on the Python of a step; in one process the physics threads wait for
it at every step. The episodes are the one-process evaluator's, bit for bit.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import signal
import time
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
import torch

from spn_torchrl.errors import EvaluatorError, SpnError
from spn_torchrl.evaluation.rollout import Episodes
from spn_torchrl.evaluation.shards import Results, ShardWorker, merge, shard_bounds, shard_requests, without_genomes
from spn_torchrl.snn.policies import PopulationSPN


def spawn_blocked_by() -> str | None:
    """Why this process cannot spawn workers, or None. A spawned child restores its parent's default start
    method, which fails for a third party's (joblib's loky workers, i.e. a ``hydra/launcher=parallel`` job)."""
    method = multiprocessing.get_start_method(allow_none=True)
    if method in (None, "spawn", "fork", "forkserver"):
        return None
    return (
        f"this process's multiprocessing start method is {method!r} (e.g. a joblib worker), whose children cannot spawn"
    )


def _serve(conn: Connection, spn: PopulationSPN, *worker_args: Any) -> None:
    """A worker process: build the shard's env, then answer requests until told to stop or orphaned."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle; it stops the workers
    try:
        worker = ShardWorker(spn, *worker_args)
        conn.send(("ok", worker.ready()))
        while (request := conn.recv()) is not None:
            method, args = request
            conn.send(("ok", getattr(worker, method)(*args)))
    except (EOFError, BrokenPipeError):  # the parent is gone
        return
    except Exception as err:  # reported to the parent, which raises it there
        error = err if isinstance(err, SpnError) else EvaluatorError(f"{type(err).__name__}: {err}")
        with contextlib.suppress(OSError):
            conn.send(("error", error))


class ProcessEvaluator:
    """The :class:`~spn_torchrl.evaluation.rollout.Evaluator` over ``processes`` worker processes, each holding a
    contiguous shard of the ``capacity`` slots."""

    def __init__(
        self,
        spn: PopulationSPN,
        env_id: str,
        capacity: int,
        backend: str,
        num_workers: int,
        max_episode_steps: int,
        processes: int,
        start_timeout_s: float = 300.0,
    ) -> None:
        self.spn = spn
        self.capacity = capacity
        self.bounds = shard_bounds(capacity, processes)
        bare = without_genomes(spn)
        context = multiprocessing.get_context("spawn")  # no fork of a process that runs threads
        self._pipes: list[Connection] = []
        self._processes: list[multiprocessing.process.BaseProcess] = []
        try:
            for index, (start, stop) in enumerate(self.bounds):
                parent, child = context.Pipe()
                process = context.Process(
                    target=_serve,
                    args=(child, bare, env_id, stop - start, backend, num_workers, max_episode_steps),
                    name=f"spn_torchrl-shard-{index}",
                    daemon=True,
                )
                process.start()
                child.close()
                self._pipes.append(parent)
                self._processes.append(process)
            deadline = time.monotonic() + start_timeout_s
            for index in range(processes):
                self._receive(index, deadline, "start")
        except BaseException:
            self.close()
            raise

    def __call__(self, genomes: torch.Tensor, seeds: int | np.ndarray) -> Episodes:
        asked = []
        for index, _, _, shard, shard_seeds in shard_requests(
            self.spn, genomes, seeds, len(self._pipes), self.capacity, "evaluator processes"
        ):
            self._send(index, ("evaluate", (shard, shard_seeds)), "evaluate")
            asked.append(index)
        return merge([self._receive(index, None, "evaluate") for index in asked])

    def gather(self, query: str) -> list:
        """Each worker's answer to a :class:`~spn_torchrl.evaluation.shards.ShardWorker` query (e.g. ``"peak_memory_mb"``)."""
        for index in range(len(self._pipes)):
            self._send(index, (query, ()), f"answer {query}")
        return [self._receive(index, None, f"answer {query}") for index in range(len(self._pipes))]

    def _send(self, index: int, message: tuple, what: str) -> None:
        try:
            self._pipes[index].send(message)
        except OSError:  # a broken pipe: the worker is gone
            raise self._died(index, what) from None

    def _receive(self, index: int, deadline: float | None, what: str) -> Results | Any:
        pipe, process = self._pipes[index], self._processes[index]
        while not pipe.poll(0.5):  # in slices, so that a dead worker is noticed
            if not process.is_alive():
                raise self._died(index, what)
            if deadline is not None and time.monotonic() > deadline:
                raise EvaluatorError(f"{self._where(index)} did not start within evaluator.start_timeout_s")
        try:
            status, value = pipe.recv()
        except (EOFError, OSError):  # closed or reset: the worker is gone
            raise self._died(index, what) from None
        if status == "error":
            raise value
        return value

    def _where(self, index: int) -> str:
        start, stop = self.bounds[index]
        return f"evaluator process {index} (slots {start}..{stop - 1})"

    def _died(self, index: int, what: str) -> EvaluatorError:
        self._processes[index].join(timeout=1)
        return EvaluatorError(
            f"{self._where(index)} died (exit code {self._processes[index].exitcode}) before it could {what}"
        )

    def close(self) -> None:
        for pipe in self._pipes:
            try:
                pipe.send(None)
            except OSError:
                pass
        for process in self._processes:
            process.join(timeout=10)
            if process.is_alive():
                process.kill()
                process.join()
        for pipe in self._pipes:
            pipe.close()
        self._pipes, self._processes = [], []
