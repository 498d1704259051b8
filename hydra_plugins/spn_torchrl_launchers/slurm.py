"""``hydra/launcher=slurm``: hydra-submitit-launcher's Slurm launcher, whose sweep waits for every job and ends, when
one did not complete, with one sentence naming each such job, its Slurm state, its own last error line and its log.

The plugin's launcher returns ``[job.results()[0] for job in jobs]``: it stops at the first job that did not
complete, with submitit's traceback and the job's whole error stream, and leaves the later jobs unread. Hydra finds
launchers only in the ``hydra_plugins`` namespace, hence this package beside ``spn_torchrl``.
"""

from __future__ import annotations

import logging
import os
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hydra.core.singleton import Singleton
from hydra.core.utils import JobReturn, filter_overrides
from omegaconf import OmegaConf

try:  # the slurm extra; Hydra imports every module of hydra_plugins at start, with or without it
    from hydra_plugins.hydra_submitit_launcher.config import BaseQueueConf
    from hydra_plugins.hydra_submitit_launcher.submitit_launcher import SlurmLauncher as SubmititSlurmLauncher
except ImportError:
    SubmititSlurmLauncher = None

log = logging.getLogger(__name__)
# the states of a job Slurm has not ended yet (submitit's list, but for UNKNOWN: what sacct says without accounting)
RUNNING = ("READY", "PENDING", "RUNNING", "REQUEUED", "COMPLETING", "PREEMPTED")


def last_error_line(stderr: str | None) -> str:
    """The job's own last ``error: ...`` or ``stopped: ...`` line (train.py's one sentence), else its last line."""
    lines = [line.strip() for line in (stderr or "").splitlines() if line.strip()]
    own = [line for line in lines if line.startswith(("error: ", "stopped: "))]
    return (own or lines or ["no error output"])[-1]


def final_state(job: Any, wait_s: float = 60.0) -> str:
    """The job's state once Slurm has recorded its end (``CANCELLED``, without ``by <uid>``); ``UNKNOWN`` without
    accounting. Its result file can appear before sacct stops reporting it RUNNING, hence the poll."""
    deadline = time.monotonic() + wait_s
    while True:
        state = job.watcher.get_state(job.job_id, mode="force").split()[0].upper()
        if state not in RUNNING or time.monotonic() > deadline:
            return state
        time.sleep(1)


def job_sentence(job: Any, overrides: Sequence[str], state: str) -> str:
    """One sentence on a job that did not complete: id, overrides, Slurm state, its own error line, its log."""
    return (
        f"job {job.job_id} ({' '.join(filter_overrides(overrides))}) ended {state}: "
        f"{last_error_line(job.stderr())} (log: {job.paths.stderr})"
    )


def results(jobs: Sequence[Any], job_overrides: Sequence[Sequence[str]]) -> list[JobReturn]:
    """The jobs' returns once all have ended; SystemExit with one sentence naming every job that did not complete
    (it passes Hydra's error report, which would add a hint line after the sentence).

    A job did not complete when submitit has no result for it or Slurm records another end than COMPLETED: a job
    cancelled with ``scancel`` stops on SIGTERM, saves its checkpoint and returns, so submitit holds its result.
    Without accounting every state reads UNKNOWN and only submitit's result counts."""
    returns, failed = [], []
    for job, overrides in zip(jobs, job_overrides):
        job.wait()
        state = final_state(job)
        try:
            result = job.results()[0]
        except Exception:  # submitit's UncompletedJobError / FailedJobError: the job's own line says why
            result = None
        if result is None or state not in ("COMPLETED", "UNKNOWN"):
            failed.append(job_sentence(job, overrides, state))
        else:
            returns.append(result)
    if failed:
        raise SystemExit(f"error: {len(failed)} of {len(jobs)} Slurm jobs did not complete: {'; '.join(failed)}")
    return returns


if SubmititSlurmLauncher is not None:

    class SlurmLauncher(SubmititSlurmLauncher):
        def launch(self, job_overrides: Sequence[Sequence[str]], initial_job_idx: int) -> Sequence[JobReturn]:
            # hydra-submitit-launcher 1.2's BaseSubmititLauncher.launch, but for its last line (see the module docstring)
            import submitit

            assert self.config is not None
            params = dict(self.params)
            init_keys = {"submitit_folder", "max_num_timeout"}
            executor = submitit.AutoExecutor(
                cluster=self._EXECUTOR,
                folder=params["submitit_folder"],
                **{f"{self._EXECUTOR}_max_num_timeout": params["max_num_timeout"]}
                if "max_num_timeout" in params
                else {},
            )
            base = set(OmegaConf.structured(BaseQueueConf).keys())
            executor.update_parameters(
                **{k if k in base else f"{self._EXECUTOR}_{k}": v for k, v in params.items() if k not in init_keys}
            )
            log.info(f"Submitit '{self._EXECUTOR}' sweep output dir : {self.config.hydra.sweep.dir}")
            sweep_dir = Path(str(self.config.hydra.sweep.dir))
            sweep_dir.mkdir(parents=True, exist_ok=True)
            if "mode" in self.config.hydra.sweep:
                os.chmod(sweep_dir, mode=int(str(self.config.hydra.sweep.mode), 8))
            job_params = []
            for idx, overrides in enumerate(job_overrides, start=initial_job_idx):
                log.info(f"\t#{idx} : {' '.join(filter_overrides(overrides))}")
                job_params.append((list(overrides), "hydra.sweep.dir", idx, f"job_id_for_{idx}", Singleton.get_state()))
            jobs = executor.map_array(self, *zip(*job_params))
            for job in jobs:
                log.info(f"\tjob {job.job_id} submitted")
            return results(jobs, job_overrides)
