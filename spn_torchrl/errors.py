"""The project's user-facing errors: each carries one sentence naming what is wrong."""

from __future__ import annotations

import signal


class SpnError(Exception):
    """Base of the errors a user can fix (bad config, unknown env, unusable checkpoint)."""


class ConfigError(SpnError, ValueError):
    """A config value is out of range or inconsistent; the message names the field."""


class CheckpointError(SpnError):
    """A checkpoint is corrupt or belongs to another task or architecture."""


class EvaluatorError(SpnError):
    """A remote evaluator could not start, lost a worker, or did not answer in time."""


class RunFileError(SpnError, OSError):
    """A file of a run could not be written: the message names the path and what was expected."""


class RunLockedError(SpnError):
    """The run directory is held by another live run."""


class NonFiniteError(SpnError):
    """A return, loss or genome became NaN or infinite: the run stops after its last finite checkpoint."""


class RunInterrupted(BaseException):
    """SIGINT or SIGTERM stopped a run; its checkpoint is consistent and it can be resumed. A BaseException, as
    KeyboardInterrupt is, so that no library's ``except Exception`` swallows it."""

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
