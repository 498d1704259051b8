"""What a run shows: on a terminal a tqdm bar (generation of total, rate, last return, time left) under one log line
per generation; through a pipe only the log lines."""

from __future__ import annotations

import fcntl
import io
import math
import os
import pty
import re
import struct
import subprocess
import termios

import pytest
from conftest import ROOT, TINY, train_command

from spn_torchrl.terminal import last_return, progress_bar


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_the_bar_counts_rows_with_their_return_on_a_terminal():
    screen = Terminal()
    with progress_bar(5, 1, "gen", screen) as show:
        show(2, {"eval_return": 12.5})
        show(3, {"eval_return": math.nan, "train_return": 7.25})
    text = screen.getvalue()
    assert "3/5" in text and "gen" in text and "return 7.25" in text and "1/5" in text  # resumed after 1


def test_off_a_terminal_or_switched_off_the_bar_writes_nothing():
    for stream, enabled in ((io.StringIO(), True), (Terminal(), False)):
        with progress_bar(5, 0, "gen", stream, enabled=enabled) as show:
            show(1, {"eval_return": 1.0})
        assert stream.getvalue() == ""


def test_last_return_is_the_evaluation_else_the_training_return():
    assert last_return({"eval_return": 3.0, "train_return": 1.0}) == 3.0
    assert last_return({"eval_return": math.nan, "train_return": 1.0}) == 1.0


TINY_RUN = ["env=cartpole", *TINY]  # 2 generations
ENV = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}


def on_a_terminal(cmd: list[str]) -> str:
    """Everything ``cmd`` writes to a pseudo-terminal of 30 rows by 120 columns (its stdout and stderr)."""
    main, child = pty.openpty()
    fcntl.ioctl(child, termios.TIOCSWINSZ, struct.pack("HHHH", 30, 120, 0, 0))
    proc = subprocess.Popen(cmd, cwd=ROOT, env=ENV, stdin=child, stdout=child, stderr=child)
    os.close(child)
    chunks = []
    while True:
        try:
            chunk = os.read(main, 65536)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        chunks.append(chunk)
    os.close(main)
    assert proc.wait(timeout=600) == 0, b"".join(chunks).decode(errors="replace")[-3000:]
    return b"".join(chunks).decode(errors="replace")


@pytest.mark.slow
def test_a_run_on_a_terminal_shows_the_bar_and_through_a_pipe_one_line_per_generation(tmp_path):
    screen = on_a_terminal(train_command(tmp_path / "tty", *TINY_RUN))
    print(screen)
    assert re.search(r"2/2 \[[0-9:]+<[0-9:]+, +[0-9.]+(s/gen|gen/s), return [0-9.]+\]", screen), screen[-2000:]
    assert all(screen.count(f"gen {g}/2 ") == 1 for g in (1, 2))  # the log lines, each once, above the bar

    plain = on_a_terminal(train_command(tmp_path / "off", *TINY_RUN, "logger.progress_bar=false"))
    assert "2/2 [" not in plain and [int(g) for g in re.findall(r"gen (\d+)/2 ", plain)] == [1, 2]

    piped = subprocess.run(
        train_command(tmp_path / "pipe", *TINY_RUN), cwd=ROOT, env=ENV, capture_output=True, text=True, timeout=600
    )
    assert piped.returncode == 0, piped.stderr[-3000:]
    out = piped.stdout + piped.stderr
    assert "\r" not in out and "2/2 [" not in out
    assert [int(g) for g in re.findall(r"gen (\d+)/2 ", out)] == [1, 2]
