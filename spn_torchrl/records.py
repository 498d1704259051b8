"""What a run writes: atomic files, progress.csv, and metrics through torchrl's loggers (CSV, W&B)."""

from __future__ import annotations

import configparser
import contextlib
import csv
import errno
import functools
import io
import logging
import netrc
import os
import socket
import stat
import subprocess
import tempfile
import threading
import urllib.parse
import urllib.request
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import torch

from spn_torchrl.config import RunConfig, config_dict
from spn_torchrl.errors import ConfigError, RunFileError

log = logging.getLogger("spn_torchrl")
_UMASK_LOCK = threading.Lock()
SOURCE_ROOT = Path(__file__).resolve().parents[1]  # the checkout when the package runs from one


def source_commit(root: Path = SOURCE_ROOT) -> str | None:
    """The commit of the code in ``root`` when ``root`` is the top of a git checkout whose tracked files have no
    uncommitted changes; None otherwise (an installed package, no git, or changes)."""

    def git(*args: str) -> str | None:
        try:
            done = subprocess.run(["git", "-C", str(root), *args], capture_output=True, text=True, timeout=60)
        except (OSError, subprocess.SubprocessError):
            return None
        return done.stdout.strip() if done.returncode == 0 else None

    top = git("rev-parse", "--show-toplevel")
    if top is None or Path(top).resolve() != root.resolve():  # a package inside another project's checkout
        return None
    if git("status", "--porcelain", "--untracked-files=no") != "":
        return None
    return git("rev-parse", "HEAD")


def current_umask() -> int:
    """This process's umask, read without changing it where Linux's /proc/self/status tells it."""
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    # os.umask reads only by setting: set it back at once (a file another thread creates between the two calls
    # gets mode & ~0o022; the lock keeps this module's own writers apart)
    with _UMASK_LOCK:
        mask = os.umask(0o022)
        os.umask(mask)
    return mask


def write_atomic(path: Path, data: bytes | str) -> None:
    """Write a file so that a reader (or a killed run) sees either the old or the new content, with the mode
    ``open(path, "w")`` gives: an existing file's own, else 0o666 less the umask. A failure raises
    :class:`~spn_torchrl.errors.RunFileError`."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        try:
            mode = stat.S_IMODE(os.stat(path).st_mode)
        except FileNotFoundError:
            mode = 0o666 & ~current_umask()
        fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")  # mode 0o600
    except OSError as err:
        raise run_file_error(path, err) from None
    try:
        with os.fdopen(fd, "wb") as f:
            os.fchmod(f.fileno(), mode)
            f.write(data.encode() if isinstance(data, str) else data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as err:
        Path(tmp).unlink(missing_ok=True)
        if isinstance(err, OSError):
            raise run_file_error(path, err) from None
        raise


_WRITE_ERRORS = {
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "the disk quota is exceeded",
    errno.EROFS: "the file system is read-only",
}


def run_file_error(path: Path, err: OSError) -> RunFileError:
    """One sentence for an error met writing a run's file ``path``: the path and what was expected there."""
    path = Path(path)
    if path.is_dir():
        return RunFileError(f"{path} is a directory, expected a file")
    for parent in reversed(path.parents):
        if parent.exists() and not parent.is_dir():
            return RunFileError(f"{parent} is a file, expected a directory (to hold {path})")
    if err.errno in (errno.EACCES, errno.EPERM):
        nearest = next((parent for parent in path.parents if parent.exists()), path.parent)
        return RunFileError(f"cannot write {path}: the directory {nearest} is not writable ({err.strerror})")
    reason = _WRITE_ERRORS.get(err.errno, err.strerror or type(err).__name__)
    return RunFileError(f"cannot write {path}: {reason}")


def run_dir_problem(path: Path) -> str | None:
    """Why ``path`` cannot be a run directory, before anything is written there: it, or a folder above it, is a
    file or a dangling symbolic link, or the directory (else its deepest existing folder) is not writable. None
    where it is a directory this process can write or can be made one."""
    path = Path(path).absolute()
    deepest = Path(path.anchor)
    for where in (*reversed(path.parents), path):
        if where.is_symlink() and not where.exists():
            return f"{where} is a symbolic link to {os.readlink(where)}, which does not exist: expected a directory"
        if where.exists() and not where.is_dir():
            held = "" if where == path else f" (to hold {path})"
            return f"{where} is a file, expected a directory{held}"
        if where.exists():
            deepest = where
    if not os.access(deepest, os.W_OK | os.X_OK):
        held = "" if deepest == path else f" (to hold {path})"
        return f"{deepest} is not writable by this user{held}: expected a directory it can write"
    return None


def save_torch_atomic(obj: Any, path: Path) -> None:
    """``torch.save`` through :func:`write_atomic`."""
    buf = io.BytesIO()
    torch.save(obj, buf)
    write_atomic(path, buf.getvalue())


class Progress:
    """progress.csv: one row per generation or iteration, rewritten atomically after each."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)

    def write(self, rows: list[Mapping[str, Any]]) -> None:
        """The file holds exactly ``rows`` (the columns of the first)."""
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=list(rows[0]), extrasaction="ignore")
        writer.writeheader()
        writer.writerows(rows)
        write_atomic(self.path, out.getvalue())


def read_progress(path: Path) -> list[dict[str, Any]]:
    """Rows of a progress.csv with numbers parsed (empty list if there is no file)."""
    path = Path(path)
    if not path.exists():
        return []
    with open(path, newline="") as f:
        return [{k: _number(v) for k, v in row.items()} for row in csv.DictReader(f)]


def _number(text: str) -> Any:
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    return text


def trim_csv_logs(run_dir: Path, last_step: int) -> int:
    """Cut the CSV logger's scalar files (``run_dir/logs/*/scalars/**/*.csv``, lines ``step,value``) to what a
    checkpoint holds: one row per step up to ``last_step`` (a repeated step keeps its last row), none for a
    run without a checkpoint (``last_step=0``); rewritten atomically. Returns the number of rows dropped.

    torchrl's CSVLogger only appends, and a run logs a row before the checkpoint that holds it is written, so
    a run killed in between logs that row again when it resumes. Call this before the resumed run's logger
    opens its files: a file the logger already holds open keeps receiving rows after it is replaced."""
    dropped = 0
    for path in sorted(Path(run_dir).glob("logs/*/scalars/**/*.csv")):
        text = path.read_text()
        lines = text.split("\n")
        torn = lines.pop()  # "" where the file ends with a newline, else a torn last write: dropped
        rows: dict[float, str] = {}
        for line in lines:
            step = _csv_step(line)
            if step is not None and step <= last_step:
                rows[step] = line
        kept = "".join(line + "\n" for line in rows.values())
        if kept == text:
            continue
        dropped += len(lines) + bool(torn) - len(rows)
        if kept:
            write_atomic(path, kept)
        else:
            path.unlink()
    if dropped:
        log.info("dropped %d rows of %s/logs that the checkpoint (step %d) does not hold", dropped, run_dir, last_step)
    return dropped


def _csv_step(line: str) -> float | None:
    """The step of a CSVLogger line ``step,value``, None for a malformed one."""
    step, comma, value = line.partition(",")
    try:
        return float(step) if comma and value else None
    except ValueError:
        return None


WANDB_PROBE_S = 3.0  # how long a TCP connect to the W&B server may take before the run decides it is unreachable
WANDB_DEFAULT_URL = "https://api.wandb.ai"  # wandb's own default base URL


def wandb_mode(requested: str) -> str:
    """The mode of the run's W&B logger, decided in at most :data:`WANDB_PROBE_S` s: ``offline`` and ``disabled``
    as asked; ``online`` where there is an API key and the server answers a TCP connect, else
    :class:`~spn_torchrl.errors.ConfigError` (one sentence: what is missing); ``auto`` (``WANDB_MODE`` if set,
    else) offline without an API key, online where the server answers, else offline, logged in one sentence."""
    asked = f"logger.mode={requested}"
    if requested == "auto" and os.environ.get("WANDB_MODE"):
        requested, asked = os.environ["WANDB_MODE"], f"WANDB_MODE={os.environ['WANDB_MODE']}"
    if requested not in ("online", "auto"):
        return requested
    url = wandb_base_url()
    return _wandb_decision(requested, asked, url, wandb_has_key(url))


@functools.cache
def _wandb_decision(mode: str, asked: str, url: str, has_key: bool) -> str:
    """:func:`wandb_mode`'s decision, once per process (a run's check before any env starts, then its logger)."""
    if not has_key:
        if mode == "auto":
            return "offline"
        raise ConfigError(
            f"{asked} needs a W&B API key for {url} (WANDB_API_KEY, or the ~/.netrc entry of wandb login): set one, "
            "or use logger.mode=offline (upload later with wandb sync)"
        )
    reason = unreachable(url, WANDB_PROBE_S)
    if reason is None:
        return "online"
    if mode == "online":
        raise ConfigError(
            f"{asked} but the W&B server {url} cannot be reached ({reason}): check the network or WANDB_BASE_URL, "
            "or use logger.mode=offline (upload later with wandb sync)"
        )
    log.warning("logger.mode=auto: the W&B server %s cannot be reached (%s): logging offline", url, reason)
    return "offline"


def wandb_base_url() -> str:
    """The W&B server this process would talk to: ``WANDB_BASE_URL``, else the ``base_url`` that ``wandb login
    --host`` wrote into wandb's settings file, else :data:`WANDB_DEFAULT_URL`."""
    if os.environ.get("WANDB_BASE_URL"):
        return os.environ["WANDB_BASE_URL"].rstrip("/")
    config_dir = Path(os.environ.get("WANDB_CONFIG_DIR") or Path.home() / ".config" / "wandb")
    settings = configparser.ConfigParser()
    with contextlib.suppress(OSError, configparser.Error):
        settings.read(config_dir / "settings")
        return settings.get("default", "base_url", fallback=WANDB_DEFAULT_URL).rstrip("/")
    return WANDB_DEFAULT_URL


def wandb_has_key(url: str) -> bool:
    """Whether W&B has an API key for ``url``: ``WANDB_API_KEY``, or the netrc entry of its host."""
    if os.environ.get("WANDB_API_KEY"):
        return True
    try:
        return netrc.netrc().authenticators(urllib.parse.urlsplit(url).hostname or "") is not None
    except (OSError, netrc.NetrcParseError):
        return False


def unreachable(url: str, timeout_s: float) -> str | None:
    """Why a TCP connect to ``url``'s host (or the proxy that serves it) fails within ``timeout_s`` (name lookup
    included), None where it succeeds."""
    parts = urllib.parse.urlsplit(url)
    host, port = parts.hostname or "", parts.port or (443 if parts.scheme == "https" else 80)
    proxy = urllib.request.getproxies().get(parts.scheme)
    if proxy and not urllib.request.proxy_bypass(host):
        proxied = urllib.parse.urlsplit(proxy if "://" in proxy else f"http://{proxy}")
        host, port = proxied.hostname or "", proxied.port or 80
    outcome: list[str | None] = []

    def connect() -> None:
        try:
            socket.create_connection((host, port), timeout=timeout_s).close()
            outcome.append(None)
        except OSError as err:
            outcome.append(f"{host}:{port}: {err.strerror or err}")

    probe = threading.Thread(target=connect, daemon=True)  # a name lookup ignores the socket's timeout
    probe.start()
    probe.join(timeout_s)
    return outcome[0] if outcome else f"{host}:{port}: no answer within {timeout_s:g} s"


def logger_run_id(logger) -> str | None:
    """The W&B run id of a logger (to resume the same W&B run), None for other loggers."""
    from torchrl.record.loggers import WandbLogger

    return logger.experiment.id if isinstance(logger, WandbLogger) else None


def sweep_name() -> str | None:
    """The name of this job's Hydra multirun directory (shared by all jobs of a sweep), None outside a multirun."""
    from hydra.core.hydra_config import HydraConfig
    from hydra.types import RunMode

    if not HydraConfig.initialized():
        return None
    hydra_cfg = HydraConfig.get()
    if hydra_cfg.mode != RunMode.MULTIRUN:
        return None
    return Path(hydra_cfg.sweep.dir).name


def make_logger(cfg: RunConfig, run_dir: Path, run_name: str, run_id: str | None = None):
    """A torchrl logger for the run (``None`` for ``logger.backend=none``). W&B runs of one Hydra sweep share
    the group ``logger.group``, by default the sweep directory's name."""
    backend = cfg.logger.backend
    if backend == "none":
        return None
    if backend == "csv":
        from torchrl.record.loggers import CSVLogger

        try:
            return CSVLogger(exp_name=run_name, log_dir=str(run_dir / "logs"))
        except OSError as err:
            raise run_file_error(run_dir / "logs" / run_name / "scalars", err) from None
    from torchrl.record.loggers import WandbLogger

    mode = wandb_mode(cfg.logger.mode)
    os.environ.setdefault("WANDB_SILENT", "true")
    return WandbLogger(
        exp_name=run_name,
        save_dir=str(run_dir),
        id=run_id,
        project=cfg.logger.project,
        entity=cfg.logger.entity,
        group=cfg.logger.group or sweep_name(),
        mode=mode,
        offline=mode == "offline",
        config=config_dict(cfg),
        reinit="create_new",  # runs in lockstep: one W&B run each, open side by side in one process
    )


def close_logger(logger, exit_code: int = 0) -> None:
    """Finish the run's logger; the W&B run of a job that failed or was stopped is marked failed with the job's
    exit code, not left running. A logger that cannot be closed then is logged, and the job's own error stands."""
    if logger is None:
        return
    from torchrl.record.loggers import WandbLogger

    if not exit_code:
        logger.close()
        return
    try:
        if isinstance(logger, WandbLogger):
            logger.experiment.finish(exit_code=exit_code)  # the close() below then finds the run finished
        logger.close()
    except Exception as err:  # the job's own error or signal is what the run ends with, not the logger's
        # e.g. Slurm's scancel sends SIGTERM to every process of the job, W&B's service too, which then drops us
        log.warning("the logger was not closed (exit code %d not recorded): %s: %s", exit_code, type(err).__name__, err)
