"""The run lifecycle the GA and PPO share: open or resume a run directory under the config contract, record its
rows (progress.csv, logger) and checkpoints, and end it cleanly on success, failure or a signal.

The config contract: a checkpoint holds the run's resolved config. A resume compares the new config with it; a
field that changes results is refused (one sentence naming each such field, old and new value), a field that
cannot (:data:`SAFE`) is allowed and logged, and the budget (:data:`BUDGET`) may grow. The checkpoint also holds
every row written so far, so progress.csv is restored from it on resume.
"""

from __future__ import annotations

import contextlib
import fcntl
import logging
import math
import os
import shlex
import signal
import sys
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from hydra.experimental.callback import Callback
from omegaconf import DictConfig, OmegaConf

from spn_torchrl import checkpoint
from spn_torchrl.config import RunConfig, config_dict, config_yaml
from spn_torchrl.errors import CheckpointError, ConfigError, NonFiniteError, RunInterrupted, RunLockedError
from spn_torchrl.records import (
    Progress,
    close_logger,
    logger_run_id,
    make_logger,
    run_dir_problem,
    run_file_error,
    source_commit,
    trim_csv_logs,
    write_atomic,
)
from spn_torchrl.terminal import Show, progress_bar

log = logging.getLogger("spn_torchrl")

# fields that cannot change a run's results: a resume may change them (logged)
SAFE = ("run_name", "torch_threads", "env.threads", "logger", "evaluator", "lockstep")
UNCOMPARED = ("resume",)  # the act of resuming itself, not a change to log or refuse
# fields added after runs were written, with the value every earlier run had: a saved config without one reads so
ADDED = {"normalize_observations": False}
# the budget of each kind of run: a resume may raise it (to at least what is done), and the extended run writes the
# rows an uninterrupted run of the new budget writes
BUDGET = {"ga": "algo.generations", "ec": "algo.generations", "ppo": "algo.total_env_steps"}
UNIT = {"ga": "gen", "ec": "gen", "ppo": "iter"}  # what the terminal's progress bar counts
PROGRESS_NAME = "progress.csv"
COMMIT_NAME = "COMMIT"
LOCK_NAME = ".lock"
RECORD_DIR = ".hydra"  # the run's config record, where Hydra would write it (conf/config.yaml turns Hydra's off)


def flatten(tree: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` -> ``{"a.b": 1}``."""
    out: dict[str, Any] = {}
    for key, value in tree.items():
        path = f"{prefix}{key}"
        if isinstance(value, Mapping):
            out.update(flatten(value, f"{path}."))
        else:
            out[path] = value
    return out


def affects_results(path: str, kind: str) -> bool:
    """Whether a config field (a dotted path) can change a run's results: not :data:`SAFE`, :data:`UNCOMPARED` or
    the budget of ``kind``."""
    safe = any(path == s or path.startswith(f"{s}.") for s in SAFE)
    return not (safe or path in UNCOMPARED or path == BUDGET.get(kind))


def config_changes(saved: Mapping[str, Any], new: Mapping[str, Any], kind: str) -> tuple[list[str], list[str]]:
    """The differences between a run's saved config and a resume's: (refused, allowed), as ``field old -> new``."""
    old_flat, new_flat = {**ADDED, **flatten(saved)}, flatten(new)
    refused, allowed = [], []
    for path in sorted(set(old_flat) | set(new_flat)):
        old, now = old_flat.get(path, "<absent>"), new_flat.get(path, "<absent>")
        if old == now or path in UNCOMPARED:
            continue
        change = f"{path} {old!r} -> {now!r}"
        (refused if affects_results(path, kind) else allowed).append(change)
    return refused, allowed


@dataclass
class Run:
    """An open run directory: its typed config, name, restored state and the places its rows go."""

    dir: Path
    cfg: RunConfig
    name: str
    kind: str
    meta: dict[str, Any]
    state: dict[str, Any] | None  # the checkpoint being resumed, None for a new run
    rows: list[dict[str, Any]] = field(default_factory=list)
    logger: Any = None
    wandb_id: str | None = None
    progress: Progress | None = None
    show: Show = lambda step, row: None  # the terminal's progress bar (a no-op off a terminal)
    saved: str | None = None  # the last checkpoint written or resumed: "generation 3", "iteration 2"

    def record(self, row: Mapping[str, Any], step: int, prefix: Mapping[str, str] | None = None) -> None:
        """Add a row, log it (metrics under ``train/``, or the prefix a column names) and show it on the progress
        bar; progress.csv gets it with the next checkpoint, so the file never holds a row the checkpoint lacks."""
        with deferred_signals():
            self.rows.append(dict(row))
            if self.logger is not None:
                prefix = prefix or {}
                metrics = {f"{prefix.get(key, 'train')}/{key}": value for key, value in row.items()}
                self.logger.log_metrics(metrics, step=step)
        self.show(step, row)

    def save(self, state: Mapping[str, Any]) -> None:
        """Write the checkpoint (the loop's ``state`` with the run's meta, config, name, W&B id and rows), then
        progress.csv with the same rows."""
        with deferred_signals():
            checkpoint.save(
                {
                    **state,
                    "meta": self.meta,
                    "config": config_dict(self.cfg),
                    "run_name": self.name,
                    "wandb_id": self.wandb_id,
                    "rows": list(self.rows),
                },
                self.dir,
            )
            if self.rows:
                self.progress.write(self.rows)
            self.saved = _step_name(state)

    def require_finite(self, what: str, values: Any, at: str) -> None:
        """Stop the run with :class:`NonFiniteError` (one sentence naming ``what``, ``at`` and the last finite
        checkpoint) where ``values`` (a tensor, a number, or several) hold a NaN or an infinity."""
        if _finite(values):
            return
        kept = (
            f"{self.dir} holds its last finite checkpoint ({self.saved})" if self.saved else "no checkpoint was written"
        )
        raise NonFiniteError(f"{what} became NaN or infinite in {at}: the run stopped there; {kept}")


def _finite(values: Any) -> bool:
    if isinstance(values, (list, tuple)):
        return all(_finite(v) for v in values)
    if isinstance(values, torch.Tensor):
        return bool(torch.isfinite(values).all())
    return math.isfinite(float(values))


def _step_name(state: Mapping[str, Any]) -> str | None:
    """``generation 3`` or ``iteration 2``: what a checkpoint's state holds."""
    for key in ("generation", "iteration"):
        if key in state:
            return f"{key} {state[key]}"
    return None


def _resume_state(cfg: RunConfig, run_dir: Path, kind: str, meta: dict[str, Any]) -> dict[str, Any] | None:
    """The checkpoint to continue (None: a new run), after the config contract; ConfigError for a directory that
    holds another run or a config that would change the results."""
    ckpt = run_dir / checkpoint.CHECKPOINT_NAME
    if not ckpt.exists():
        if (run_dir / PROGRESS_NAME).exists():
            raise ConfigError(
                f"{run_dir} holds {PROGRESS_NAME} but no {checkpoint.CHECKPOINT_NAME}: this run cannot be resumed or "
                "overwritten; use a new run directory"
            )
        if cfg.resume:
            log.info("resume=true but %s holds no checkpoint: starting a new run", run_dir)
        return None
    if not cfg.resume:
        raise ConfigError(f"{run_dir} already holds a run: pass resume=true to continue it, or use a new run directory")
    state = checkpoint.load(ckpt, expected={"format": meta["format"]})
    if state["meta"] != meta:
        changed = [f"{k} {state['meta'].get(k)!r} -> {v!r}" for k, v in meta.items() if state["meta"].get(k) != v]
        raise CheckpointError(
            f"{ckpt} belongs to another task or network ({', '.join(changed)}): use a new run directory"
        )
    refused, allowed = config_changes(state["config"], config_dict(cfg), kind)
    if refused:
        raise ConfigError(
            f"resume=true with a config that would change the results of {run_dir}: {'; '.join(refused)}; "
            "resume with the run's values or use a new run directory"
        )
    for change in allowed:
        log.info("resume: %s (does not change results)", change)
    _check_budget(cfg, state, run_dir, kind)
    return state


def _check_budget(cfg: RunConfig, state: Mapping[str, Any], run_dir: Path, kind: str) -> None:
    """ConfigError for a budget below what the run in ``run_dir`` has done (a budget may only grow)."""
    if kind != "ppo":
        asked, done, unit = cfg.algo.generations, state["generation"], "generations"
    else:
        asked, done, unit = cfg.algo.total_env_steps, state["iteration"] * cfg.algo.frames_per_batch, "env steps"
    if asked < done:
        raise ConfigError(f"{BUDGET[kind]}={asked} is below the {done} {unit} {run_dir} has done")


class RunDirCheck(Callback):
    """A Hydra callback (conf/config.yaml): a ``hydra.run.dir`` or ``hydra.sweep.dir`` that is a file or a dangling
    symbolic link ends the job with one sentence before Hydra creates it (Hydra's own error is a traceback)."""

    def on_run_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._check(config.hydra.run.dir, "hydra.run.dir")

    def on_multirun_start(self, config: DictConfig, **kwargs: Any) -> None:
        self._check(config.hydra.sweep.dir, "hydra.sweep.dir")

    @staticmethod
    def _check(path: str, field: str) -> None:
        problem = run_dir_problem(Path(path))
        if problem is not None:
            sys.exit(f"error: {field}={path}: {problem}")


def record_config(run_dir: Path, cfg: RunConfig) -> None:
    """``.hydra/config.yaml`` (the run's resolved config) and, inside a Hydra app, ``overrides.yaml`` and
    ``hydra.yaml``: what Hydra writes before the app starts, written here only once the run is accepted, so that a
    refused run leaves the directory's record as it was."""
    record = run_dir / RECORD_DIR
    write_atomic(record / "config.yaml", config_yaml(cfg))
    hydra = _hydra_config()
    if hydra is not None:
        write_atomic(record / "overrides.yaml", OmegaConf.to_yaml(hydra.overrides.task))
        write_atomic(record / "hydra.yaml", OmegaConf.to_yaml(OmegaConf.create({"hydra": hydra})))


def _hydra_config() -> Any:
    """Hydra's config of this job, None outside a Hydra app."""
    from hydra.core.hydra_config import HydraConfig

    return HydraConfig.get() if HydraConfig.initialized() else None


@contextlib.contextmanager
def run_lock(run_dir: Path) -> Iterator[None]:
    """Hold ``run_dir/.lock`` (an exclusive ``flock``) while the body runs: a second run in the directory is refused
    with :class:`RunLockedError`. The kernel releases the lock when the process ends, however it ends, so a killed
    run leaves no stuck lock; the file itself stays (removing it would let two runs lock two files)."""
    path = run_dir / LOCK_NAME
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o666)
    except PermissionError:
        try:  # an existing lock file in a directory the user made read-only: a read-only descriptor locks too
            fd = os.open(path, os.O_RDONLY | os.O_CLOEXEC)
        except OSError as err:
            raise run_file_error(path, err) from None
    except OSError as err:
        raise run_file_error(path, err) from None
    try:
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            holder = os.pread(fd, 32, 0).decode(errors="replace").strip()
            raise RunLockedError(
                f"{run_dir} is in use by a live run{f' (process {holder})' if holder.isdigit() else ''}: "
                "wait for it to end, or use a new run directory"
            ) from None
        with contextlib.suppress(OSError):  # the holder's pid, for the refusal above; the lock works without it
            os.ftruncate(fd, 0)
            os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield
    finally:
        os.close(fd)


@contextlib.contextmanager
def open_run(cfg: RunConfig, run_dir: Path, name: str, kind: str, meta: dict[str, Any], total: int) -> Iterator[Run]:
    """Open (or resume) the run in ``run_dir``, whose budget is ``total`` generations or iterations; the logger is
    finished on the way out (a W&B run marked failed with the exit code when the body raised or a signal stopped
    it), and the run's config and rows on disk are the checkpoint's. On a terminal a progress bar counts the rows."""
    state = _resume_state(cfg, run_dir, kind, meta)
    record_config(run_dir, cfg)
    record_commit(run_dir, resumed=state is not None, commit=source_commit())
    run = Run(run_dir, cfg, name, kind, meta, state)
    if state is not None:
        run.name, run.wandb_id, run.rows = state["run_name"], state["wandb_id"], list(state["rows"])
        run.saved = _step_name(state)
    run.progress = Progress(run_dir / PROGRESS_NAME)
    if run.rows:
        run.progress.write(run.rows)  # progress.csv is the checkpoint's rows, even if it was lost or cut
    exit_code = 1
    try:
        trim_csv_logs(run_dir, _last_step(run.rows))  # rows logged after the checkpoint was written
        run.logger = make_logger(cfg, run_dir, run.name, run.wandb_id)
        run.wandb_id = logger_run_id(run.logger)
        log.info("run %s in %s", run.name, run_dir)
        with progress_bar(total, _last_step(run.rows), UNIT[kind], enabled=cfg.logger.progress_bar) as run.show:
            yield run
        exit_code = 0
    except RunInterrupted as err:
        exit_code = 128 + err.signum
        raise
    finally:
        close_logger(run.logger, exit_code)


def record_commit(run_dir: Path, resumed: bool, commit: str | None) -> None:
    """``COMMIT``: the commit of the code that made the run (``commit``; None for code that is not one commit),
    written when the run starts. A resume by other code removes it: no one commit made the run any more."""
    path = run_dir / COMMIT_NAME
    if not resumed and commit is not None:
        write_atomic(path, commit + "\n")
        return
    recorded = path.read_text().strip() if path.is_file() else None
    if recorded is not None and (not resumed or recorded != commit):
        path.unlink()  # an earlier start's, or the start's of a run that other code now continues
        if resumed:
            log.warning(
                "resume: %s removed: the run started on commit %s, this code is %s",
                path,
                recorded,
                commit or "not one commit (uncommitted changes, or no checkout)",
            )
    if commit is None:
        log.info("%s not written: the code is not a git checkout without uncommitted changes", path)


def _last_step(rows: list[dict[str, Any]]) -> int:
    """The generation or iteration of the last row a checkpoint holds (0: none)."""
    if not rows:
        return 0
    return int(rows[-1].get("generation", rows[-1].get("iteration", 0)))


_critical = 0
_pending: list[int] = []


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """A section that SIGINT and SIGTERM do not cut: a signal that arrives inside is raised when it ends."""
    global _critical
    _critical += 1
    try:
        yield
    finally:
        _critical -= 1
    if _critical == 0:
        _raise_pending()


def _raise_pending() -> None:
    if _pending:
        raise RunInterrupted(_pending[0])


def _handler(signum: int, frame: Any) -> None:
    # kept pending as well: Python drops an exception raised where the signal lands in a finaliser or weakref
    # callback, and the next recorded row or checkpoint raises it then
    _pending.append(signum)
    if not _critical:
        _raise_pending()


@contextlib.contextmanager
def signals_interrupt() -> Iterator[None]:
    """SIGINT and SIGTERM raise :class:`RunInterrupted` (outside :func:`deferred_signals` sections) while the body
    runs; the previous handlers come back afterwards. A no-op outside the main thread."""
    try:
        previous = {sig: signal.signal(sig, _handler) for sig in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread
        yield
        return
    try:
        yield
    finally:
        _pending.clear()
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def resume_hint(run_dir: Path, resume: bool = True) -> str:
    """The command line (shell-quoted) that resumes the run in ``run_dir`` (``resume=False``: starts it again):
    this job's overrides plus the directory."""
    overrides: list[str] = []
    script = Path(sys.argv[0]).name or "train.py"
    with contextlib.suppress(Exception):
        hydra = _hydra_config()
        overrides = [o for o in hydra.overrides.task if not o.startswith(("resume=", "hydra.run.dir="))]
        script = f"{hydra.job.name}.py"  # the script's name, also in a Slurm job (whose argv[0] is submitit's)
    command = ["python", script, *overrides, f"hydra.run.dir={run_dir}"]
    return shlex.join(command + ["resume=true"] * resume)
