"""The project's user-facing errors: each carries one sentence naming what is wrong."""

from __future__ import annotations

import errno
import signal


class SpnError(Exception):
    """Base of the errors a user can fix (bad config, unknown env, unusable checkpoint)."""


class ConfigError(SpnError, ValueError):
    """A config value is out of range or inconsistent; the message names the field."""


class CheckpointError(SpnError):
    """A checkpoint is corrupt or belongs to another task or architecture."""


class EvaluatorError(SpnError):
    """A remote evaluator could not start, lost a worker, or did not answer in time."""


class RunFileError(SpnError):
    """A file or directory of a run cannot be written (read-only, full disk, a file where a directory belongs)."""

    @classmethod
    def of(cls, err: OSError, path: object, what: str = "a file") -> RunFileError:
        """One sentence for an OSError met while writing ``path`` (``what`` it should be)."""
        reasons = {
            errno.EACCES: "permission denied",
            errno.EPERM: "permission denied",
            errno.EROFS: "the file system is read-only",
            errno.ENOSPC: "no space left on device",
            errno.EDQUOT: "disk quota exceeded",
            errno.EISDIR: f"it is a directory, expected {what}",
            errno.ENOTDIR: f"a file stands where a directory belongs on the way to {what}",
            errno.EEXIST: f"a file stands where {what} belongs",
        }
        where = getattr(err, "filename", None) or path
        return cls(f"cannot write {where}: {reasons.get(err.errno, err.strerror or type(err).__name__)}")


class RunInterrupted(SpnError):
    """SIGINT or SIGTERM stopped a run; its checkpoint is consistent and it can be resumed."""

    def __init__(self, signum: int) -> None:
        self.signum = signum
        super().__init__(f"interrupted by {signal.Signals(signum).name}")


class DependencyError(SpnError, ImportError):
    """An optional dependency (an extra of the package) or a system library is missing."""


def require(module: str, extra: str):
    """Import an optional module, or raise :class:`DependencyError` naming the extra that provides it."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError:
        raise DependencyError(
            f'{module} is not installed: install the optional extra with pip install -e ".[{extra}]"'
        ) from None
