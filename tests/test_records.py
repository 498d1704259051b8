import os
import stat

import pytest

from spn_torchrl.records import Progress, current_umask, read_progress, wandb_mode, write_atomic


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


def test_progress_rows_roundtrip_and_truncate_on_resume(tmp_path):
    path = tmp_path / "progress.csv"
    progress = Progress(path)
    for g in range(1, 4):
        progress.append({"generation": g, "eval_return": g * 1.5, "note": "x"})
    assert read_progress(path) == [{"generation": g, "eval_return": g * 1.5, "note": "x"} for g in range(1, 4)]
    resumed = Progress(path, keep_rows=2)  # a checkpoint after generation 2: row 3 is dropped
    assert [r["generation"] for r in read_progress(path)] == [1, 2]
    resumed.append({"generation": 3, "eval_return": 9.0, "note": "y"})
    assert read_progress(path)[-1]["eval_return"] == 9.0
    Progress(path, keep_rows=0)  # a fresh run in the same file starts empty
    assert not path.exists()


@pytest.mark.parametrize(
    "env,requested,expected",
    [
        ({}, "auto", "offline"),
        ({"WANDB_API_KEY": "k"}, "auto", "online"),
        ({"WANDB_MODE": "disabled"}, "auto", "disabled"),
        ({"WANDB_API_KEY": "k"}, "offline", "offline"),
    ],
)
def test_wandb_mode_auto_is_offline_without_credentials(monkeypatch, tmp_path, env, requested, expected):
    monkeypatch.setenv("HOME", str(tmp_path))  # no ~/.netrc
    monkeypatch.delenv("NETRC", raising=False)
    for key in ("WANDB_API_KEY", "WANDB_MODE"):
        monkeypatch.delenv(key, raising=False)
    for key, value in env.items():
        monkeypatch.setenv(key, value)
    assert wandb_mode(requested) == expected
