"""Population evaluation in worker processes on this machine: ``evaluator.processes`` > 1.

Each worker process holds one shard's batched env and SPN (:class:`~spn_torchrl.evaluation.shards.ShardWorker`, built
once) and runs its episodes to their end on its own. One shard's SPN and env bookkeeping run while the other
shards' physics runs, so no core waits on the Python of a step; in one process the physics threads wait for
it at every step. The episodes are the one-process evaluator's, bit for bit.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import threading
import time
from collections.abc import Iterable
from multiprocessing.connection import Connection, wait
from typing import Any

import numpy as np
import torch

from spn_torchrl.config import LocalEvaluatorConfig
from spn_torchrl.errors import ConfigError, EvaluatorError, SpnError
from spn_torchrl.evaluation.rollout import Episodes
from spn_torchrl.evaluation.shards import Results, ShardWorker, merge, shard_bounds, shard_requests, without_genomes
from spn_torchrl.snn.observations import Norm
from spn_torchrl.snn.policies import PopulationSPN

CALL_TIMEOUT_S = LocalEvaluatorConfig.call_timeout_s  # a genome set's evaluation past this is a stall
CLOSE_GRACE_S = 5.0  # close() waits this long for workers to exit when asked, then kills the rest


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
    contiguous shard of the ``capacity`` slots. A call that gets no answer from a worker within
    ``call_timeout_s`` (None: no limit) raises :class:`~spn_torchrl.errors.EvaluatorError` naming it."""

    def __init__(
        self,
        spn: PopulationSPN,
        env_id: str,
        capacity: int,
        backend: str,
        threads: int,
        max_episode_steps: int,
        processes: int,
        start_timeout_s: float = 300.0,
        call_timeout_s: float | None = CALL_TIMEOUT_S,
    ) -> None:
        if call_timeout_s is not None and not call_timeout_s > 0:
            raise ConfigError(f"evaluator.call_timeout_s must be > 0 or null, got {call_timeout_s}")
        self.spn = spn
        self.capacity = capacity
        self.call_timeout_s = call_timeout_s
        self.bounds = shard_bounds(capacity, processes)
        bare = without_genomes(spn)
        context = multiprocessing.get_context("spawn")  # no fork of a process that runs threads
        self._pipes: list[Connection] = []
        self._processes: list[multiprocessing.process.BaseProcess] = []
        self._sender: _Sender | None = None
        try:
            for index, (start, stop) in enumerate(self.bounds):
                parent, child = context.Pipe()
                process = context.Process(
                    target=_serve,
                    args=(child, bare, env_id, stop - start, backend, threads, max_episode_steps),
                    name=f"spn_torchrl-shard-{index}",
                    daemon=True,
                )
                process.start()
                child.close()
                self._pipes.append(parent)
                self._processes.append(process)
            self._collect(range(processes), time.monotonic() + start_timeout_s, "start")
        except BaseException:
            self.close()
            raise

    def __call__(
        self, genomes: torch.Tensor, seeds: int | np.ndarray, norm: Norm | None = None, runs: np.ndarray | None = None
    ) -> Episodes:
        requests = shard_requests(
            self.spn, genomes, seeds, len(self._pipes), self.capacity, "evaluator processes", norm, runs
        )
        asked = [
            (index, ("evaluate", (shard, shard_seeds, part, shard_runs)))
            for index, _, _, shard, shard_seeds, part, shard_runs in requests
        ]
        return merge(self._ask(asked, "evaluate"))

    def gather(self, query: str) -> list:
        """Each worker's answer to a :class:`~spn_torchrl.evaluation.shards.ShardWorker` query (e.g. ``"peak_memory_mb"``)."""
        return self._ask([(index, (query, ())) for index in range(len(self._pipes))], f"answer {query}")

    def _ask(self, requests: list[tuple[int, tuple]], what: str) -> list:
        """The workers' answers to their requests, in request order, all within ``call_timeout_s``."""
        deadline = None if self.call_timeout_s is None else time.monotonic() + self.call_timeout_s
        # sent from a thread: a request larger than the pipe's buffer blocks its send while the worker is stopped
        self._sender = _Sender([(self._pipes[index], message) for index, message in requests])
        return self._collect([index for index, _ in requests], deadline, what)

    def _collect(self, indices: Iterable[int], deadline: float | None, what: str) -> list:
        indices = list(indices)
        answers: dict[int, Any] = {}
        while len(answers) < len(indices):
            waiting = [index for index in indices if index not in answers]
            ready = wait([self._pipes[index] for index in waiting], timeout=0.5)  # in slices: deaths, deadline
            for index in waiting:
                if self._pipes[index] in ready:
                    answers[index] = self._receive(index, what)
            if ready:
                continue
            for index in waiting:
                if not self._processes[index].is_alive():
                    raise self._died(index, what)
            if self._sender is not None and self._sender.error is not None:
                raise self._sender.error
            if deadline is not None and time.monotonic() > deadline:
                stopped_first = sorted(waiting, key=lambda index: not _stopped(self._processes[index].pid))
                raise self._late(stopped_first[0], what)
        return [answers[index] for index in indices]

    def _receive(self, index: int, what: str) -> Results | Any:
        try:
            status, value = self._pipes[index].recv()
        except (EOFError, OSError):  # closed or reset: the worker is gone
            raise self._died(index, what) from None
        if status == "error":
            raise value
        return value

    def _where(self, index: int, pid: bool = False) -> str:
        start, stop = self.bounds[index]
        pid_part = f", pid {self._processes[index].pid}" if pid else ""
        return f"evaluator process {index} (slots {start}..{stop - 1}{pid_part})"

    def _died(self, index: int, what: str) -> EvaluatorError:
        self._processes[index].join(timeout=1)
        return EvaluatorError(
            f"{self._where(index)} died (exit code {self._processes[index].exitcode}) before it could {what}"
        )

    def _late(self, index: int, what: str) -> EvaluatorError:
        if what == "start":
            return EvaluatorError(f"{self._where(index)} did not start within evaluator.start_timeout_s")
        state = "is stopped (SIGSTOP?)" if _stopped(self._processes[index].pid) else "is stalled or needs longer"
        return EvaluatorError(
            f"{self._where(index, pid=True)} did not {what} within evaluator.call_timeout_s={self.call_timeout_s:g} s: "
            f"it {state}"
        )

    def close(self) -> None:
        """End every worker: those that do not exit when asked within a few seconds (busy, stopped) are killed."""
        in_flight = self._sender is not None and self._sender.is_alive()
        if not in_flight:  # else a request is half-sent: no clean message can follow it
            for pipe in self._pipes:
                with contextlib.suppress(OSError):
                    os.set_blocking(pipe.fileno(), False)  # a full pipe must not block close
                    pipe.send(None)
        deadline = time.monotonic() + (0 if in_flight else CLOSE_GRACE_S)
        for process in self._processes:
            if not _stopped(process.pid):
                process.join(timeout=max(0.0, deadline - time.monotonic()))
            if process.is_alive():
                process.kill()  # SIGKILL ends a stopped process too
                process.join()
        if self._sender is not None:
            self._sender.join(timeout=5)  # its workers are gone: a blocked send fails at once
        for pipe in self._pipes:
            pipe.close()
        self._pipes, self._processes, self._sender = [], [], None


class _Sender(threading.Thread):
    """Sends requests to workers in order; stops at the first worker that is gone (the receiver reports it)."""

    def __init__(self, messages: list[tuple[Connection, tuple]]) -> None:
        super().__init__(name="spn_torchrl-evaluator-sender", daemon=True)
        self.messages = messages
        self.error: BaseException | None = None
        self.start()

    def run(self) -> None:
        try:
            for pipe, message in self.messages:
                pipe.send(message)
        except OSError:  # a broken pipe: the worker is gone
            pass
        except BaseException as err:  # e.g. a payload that cannot be pickled: raised by the caller
            self.error = err


def _stopped(pid: int | None) -> bool:
    """Whether a process is stopped (by SIGSTOP or a debugger); False where /proc cannot tell."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rpartition(")")[2].split()[0] in ("T", "t")
    except (OSError, IndexError):
        return False
