import os
import socket
import stat
import tempfile
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
from torchrl.record.loggers import CSVLogger

from spn_torchrl.config import LoggerConfig
from spn_torchrl.errors import RunFileError
from spn_torchrl.records import (
    WANDB_PROBE_S,
    Progress,
    current_umask,
    make_logger,
    read_progress,
    trim_csv_logs,
    unreachable,
    wandb_mode,
    write_atomic,
)


def test_write_atomic_replaces_whole_file(tmp_path):
    path = tmp_path / "a" / "f.txt"
    write_atomic(path, "one")
    write_atomic(path, b"two")
    assert path.read_text() == "two" and [p.name for p in path.parent.iterdir()] == ["f.txt"]


@pytest.mark.parametrize("umask", [0o022, 0o027, 0o002])
def test_write_atomic_gives_the_mode_open_gives(tmp_path, umask):
    def mode(path):
        return stat.S_IMODE(path.stat().st_mode)

    old = os.umask(umask)
    try:
        assert current_umask() == umask
        write_atomic(tmp_path / "new.csv", "x")
        with open(tmp_path / "plain.csv", "w") as f:
            f.write("x")
        assert mode(tmp_path / "new.csv") == mode(tmp_path / "plain.csv") == 0o666 & ~umask
        (tmp_path / "new.csv").chmod(0o640)  # like open(path, "w"), a rewrite keeps the file's own mode
        write_atomic(tmp_path / "new.csv", "y")
        assert mode(tmp_path / "new.csv") == 0o640 and (tmp_path / "new.csv").read_text() == "y"
    finally:
        os.umask(old)


def write_error(path) -> str:
    """The message write_atomic raises for ``path``, '' if it writes."""
    try:
        write_atomic(path, "x")
    except RunFileError as err:
        return str(err)
    return ""


def write_error_unprivileged(path) -> str:
    """:func:`write_error` where file permissions apply: for root, in a child process running as nobody."""
    if os.geteuid() != 0:
        return write_error(path)
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child only writes and reports: no pytest teardown, no atexit
        try:
            os.setgid(65534)
            os.setuid(65534)
            os.write(write, write_error(path).encode())
        finally:
            os._exit(0)
    os.close(write)
    with os.fdopen(read) as f:
        message = f.read()
    os.waitpid(pid, 0)
    return message


def test_write_atomic_errors_name_the_path_and_what_was_expected(tmp_path):
    with tempfile.TemporaryDirectory(dir="/tmp") as top:  # tmp_path's parents may be closed to other users
        Path(top).chmod(0o755)
        read_only = Path(top) / "run"
        read_only.mkdir(mode=0o555)
        assert write_error_unprivileged(read_only / "progress.csv") == (
            f"cannot write {read_only}/progress.csv: the directory {read_only} is not writable (Permission denied)"
        )
        assert write_error_unprivileged(read_only / "logs" / "x.csv") == (
            f"cannot write {read_only}/logs/x.csv: the directory {read_only} is not writable (Permission denied)"
        )
        assert not list(read_only.iterdir())
    (tmp_path / "progress.csv").mkdir()
    assert write_error(tmp_path / "progress.csv") == f"{tmp_path}/progress.csv is a directory, expected a file"
    (tmp_path / "run").write_text("")
    for path in (tmp_path / "run" / "checkpoint.pt", tmp_path / "run" / "logs" / "x.csv"):
        assert write_error(path) == f"{tmp_path}/run is a file, expected a directory (to hold {path})"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["progress.csv", "run"]  # no temporary file is left
    with pytest.raises(RunFileError, match="progress.csv is a directory, expected a file"):
        Progress(tmp_path / "progress.csv").write([{"generation": 1}])
    (tmp_path / "run").unlink()
    (tmp_path / "run").mkdir()
    (tmp_path / "run" / "logs").write_text("")  # a file where the CSV logger's directory belongs
    with pytest.raises(
        RunFileError, match=r"run/logs is a file, expected a directory \(to hold .*/logs/name/scalars\)"
    ):
        make_logger(SimpleNamespace(logger=LoggerConfig(backend="csv")), tmp_path / "run", "name")


def test_progress_holds_exactly_the_rows_it_is_given(tmp_path):
    path = tmp_path / "progress.csv"
    rows = [{"generation": g, "eval_return": g * 1.5, "note": "x"} for g in range(1, 4)]
    Progress(path).write(rows)
    assert read_progress(path) == rows
    Progress(path).write(rows[:2])  # a resumed run: the checkpoint's rows
    assert read_progress(path) == rows[:2]


def log_rows(run_dir, name, steps, run):
    logger = CSVLogger(exp_name=name, log_dir=str(run_dir / "logs"))
    for step in steps:
        metrics = {"train/return": 10.0 * step + run, "train/generation": step}
        if step % 2 == 0:
            metrics["eval/return"] = step + 0.5  # a metric of some steps only, like PPO's eval_return
        logger.log_metrics(metrics, step=step)
    logger.close()
    del logger  # torchrl's CSVExperiment closes its files when collected


def logged(run_dir, name, metric):
    path = run_dir / "logs" / name / "scalars" / f"{metric}.csv"
    return [tuple(float(x) for x in line.split(",")) for line in path.read_text().splitlines()]


def test_trimmed_csv_logs_resume_without_duplicates(tmp_path):
    log_rows(tmp_path, "run", range(1, 6), run=0)  # logged up to 5, killed with a checkpoint holding 3 rows
    eval_file = tmp_path / "logs" / "run" / "scalars" / "eval" / "return.csv"
    mode = eval_file.stat().st_mode
    with open(eval_file, "a") as f:
        f.write("6,6.")  # a torn last write
    assert trim_csv_logs(tmp_path, 3) == 2 + 2 + 2  # steps 4, 5 of each metric, the torn line
    log_rows(tmp_path, "run", range(4, 7), run=1)  # the resumed run logs 4..6 again
    assert logged(tmp_path, "run", "train/return") == [(1, 10), (2, 20), (3, 30), (4, 41), (5, 51), (6, 61)]
    assert logged(tmp_path, "run", "train/generation") == [(s, s) for s in range(1, 7)]
    assert logged(tmp_path, "run", "eval/return") == [(2, 2.5), (4, 4.5), (6, 6.5)]
    assert eval_file.stat().st_mode == mode
    assert trim_csv_logs(tmp_path, 6) == 0 and trim_csv_logs(tmp_path / "none", 6) == 0
    log_rows(tmp_path, "stale", [1], run=0)  # an attempt under another name, killed before any checkpoint
    trim_csv_logs(tmp_path, 0)  # the new run that follows it: no row is held
    assert not list((tmp_path / "logs").glob("*/scalars/**/*.csv"))


def test_trim_csv_logs_keeps_the_last_of_repeated_steps(tmp_path):
    path = tmp_path / "logs" / "run" / "scalars" / "train" / "x.csv"
    path.parent.mkdir(parents=True)
    path.write_text("1,1.0\n2,2.0\n2,2.5\nnot a row\n3,3.0\n")  # a log written before this fix
    assert trim_csv_logs(tmp_path, 3) == 2
    assert path.read_text() == "1,1.0\n2,2.5\n3,3.0\n"


@pytest.mark.parametrize(
    "env,requested,expected",
    [
        ({}, "auto", "offline"),
        ({"WANDB_API_KEY": "k"}, "auto", "online"),  # the server (a local socket) answers
        ({"WANDB_MODE": "disabled"}, "auto", "disabled"),
        ({"WANDB_API_KEY": "k"}, "offline", "offline"),
    ],
)
def test_wandb_mode_auto_is_offline_without_credentials(monkeypatch, tmp_path, env, requested, expected):
    monkeypatch.setenv("HOME", str(tmp_path))  # no ~/.netrc
    monkeypatch.delenv("NETRC", raising=False)
    for key in ("WANDB_API_KEY", "WANDB_MODE", "WANDB_BASE_URL"):
        monkeypatch.delenv(key, raising=False)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    with socket.create_server(("127.0.0.1", 0)) as server:
        monkeypatch.setenv("WANDB_BASE_URL", f"http://127.0.0.1:{server.getsockname()[1]}")
        assert wandb_mode(requested) == expected


def test_the_server_probe_gives_up_on_a_server_that_never_answers_within_its_bound():
    """A listener whose accept queue is full drops new SYNs, so a connect to it hangs: unreachable() says so after
    its timeout (the 3 s W&B probe's bound), not after the kernel's minutes of retries."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen(0)
        port = server.getsockname()[1]
        fillers = [socket.socket() for _ in range(4)]
        for sock in fillers:
            sock.setblocking(False)
            try:
                sock.connect(("127.0.0.1", port))
            except BlockingIOError:
                pass
        started = time.monotonic()
        reason = unreachable(f"http://127.0.0.1:{port}", WANDB_PROBE_S)
        waited = time.monotonic() - started
        for sock in fillers:
            sock.close()
    assert reason == f"127.0.0.1:{port}: no answer within {WANDB_PROBE_S:g} s"
    assert WANDB_PROBE_S <= waited < WANDB_PROBE_S + 1.0
