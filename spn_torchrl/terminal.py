"""What a run shows on a terminal: a tqdm progress bar (generation or iteration of total, the rate, the last return,
the time left) under the run's log lines. Where stderr is not a terminal (Slurm logs, CI, a pipe) there is no bar and
the run's output stays one plain log line per generation or iteration."""

from __future__ import annotations

import contextlib
import logging
import math
import sys
from collections.abc import Callable, Iterator, Mapping
from typing import IO, Any

Show = Callable[[int, Mapping[str, Any]], None]


def last_return(row: Mapping[str, Any]) -> float:
    """The row's evaluation return, or its training return where the row has no evaluation (PPO between evals)."""
    value = row.get("eval_return", math.nan)
    return row.get("train_return", math.nan) if isinstance(value, float) and math.isnan(value) else value


@contextlib.contextmanager
def progress_bar(
    total: int, done: int, unit: str, stream: IO[str] | None = None, enabled: bool = True
) -> Iterator[Show]:
    """``show(step, row)`` moves the bar to ``step`` of ``total`` (``done`` already run, e.g. before a resume) with
    the row's last return; a no-op where ``stream`` (default stderr) is not a terminal or the bar is not
    ``enabled`` (``logger.progress_bar=false``). While the bar is up, the
    console handlers of the root logger write through tqdm, so their lines go above the bar instead of through it."""
    stream = stream or sys.stderr
    if not enabled or not stream.isatty():
        yield lambda step, row: None
        return
    from tqdm import tqdm
    from tqdm.contrib.logging import logging_redirect_tqdm

    with (
        tqdm(total=total, initial=done, unit=unit, file=stream, dynamic_ncols=True, smoothing=0.1) as bar,
        logging_redirect_tqdm(loggers=[logging.getLogger()]),
    ):

        def show(step: int, row: Mapping[str, Any]) -> None:
            bar.set_postfix_str(f"return {last_return(row):.2f}", refresh=False)
            bar.update(step - bar.n)

        yield show
