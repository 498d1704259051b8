"""The commit a run records (COMMIT): which code counts as one commit, and what a resume does to the record."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

from spn_torchrl.lifecycle import COMMIT_NAME, record_commit
from spn_torchrl.records import source_commit


def git(root: Path, *args: str) -> str:
    done = subprocess.run(
        ["git", "-C", str(root), "-c", "user.name=t", "-c", "user.email=t@t", *args],
        capture_output=True,
        text=True,
        check=True,
    )
    return done.stdout.strip()


@pytest.fixture
def checkout(tmp_path: Path) -> Path:
    root = tmp_path / "checkout"
    root.mkdir()
    git(root, "init", "-q")
    (root / "code.py").write_text("x = 1\n")
    git(root, "add", "code.py")
    git(root, "commit", "-q", "-m", "code")
    return root


def test_a_clean_checkout_is_its_head(checkout: Path) -> None:
    assert source_commit(checkout) == git(checkout, "rev-parse", "HEAD")
    (checkout / "outputs").mkdir()
    (checkout / "outputs" / "progress.csv").write_text("generation\n")  # untracked files are not the code
    assert source_commit(checkout) == git(checkout, "rev-parse", "HEAD")


def test_uncommitted_changes_a_subfolder_or_no_checkout_are_no_commit(checkout: Path, tmp_path: Path) -> None:
    (checkout / "code.py").write_text("x = 2\n")
    assert source_commit(checkout) is None
    git(checkout, "checkout", "-q", "code.py")
    site = checkout / "venv" / "site-packages"  # a package installed inside another project's checkout
    site.mkdir(parents=True)
    assert source_commit(site) is None
    assert source_commit(tmp_path) is None


def test_a_new_run_records_its_commit_and_a_resume_by_other_code_removes_it(tmp_path: Path) -> None:
    path = tmp_path / COMMIT_NAME
    record_commit(tmp_path, resumed=False, commit="a" * 40)
    assert path.read_text() == "a" * 40 + "\n"
    record_commit(tmp_path, resumed=True, commit="a" * 40)
    assert path.read_text() == "a" * 40 + "\n"
    record_commit(tmp_path, resumed=True, commit="b" * 40)
    assert not path.exists()
    record_commit(tmp_path, resumed=True, commit="a" * 40)  # gone for good: the run has two commits
    assert not path.exists()


def test_a_start_without_one_commit_leaves_no_record(tmp_path: Path) -> None:
    path = tmp_path / COMMIT_NAME
    path.write_text("c" * 40 + "\n")  # an earlier start's, in a directory with no checkpoint
    record_commit(tmp_path, resumed=False, commit=None)
    assert not path.exists()
    path.write_text("c" * 40 + "\n")
    record_commit(tmp_path, resumed=True, commit=None)
    assert not path.exists()
