"""Tiny real GA runs (train.py in a subprocess), shared by the tests of play, pictures and export."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def train(run_dir: Path, *overrides: str) -> Path:
    """Run train.py with ``overrides`` into ``run_dir``; fail the test with its output if it fails."""
    cmd = [sys.executable, str(ROOT / "train.py"), f"hydra.run.dir={run_dir}", "logger=csv", *overrides]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, f"{' '.join(cmd)} failed:\n{done.stdout}\n{done.stderr}"
    return run_dir


@pytest.fixture(scope="session")
def cartpole_run(tmp_path_factory) -> Path:
    """CartPole, 2 generations of 10 (2 elite candidates x 5 episodes)."""
    return train(
        tmp_path_factory.mktemp("runs") / "cartpole",
        "env=cartpole", "algo.generations=2", "algo.population=10", "algo.elite_candidates=2", "algo.elite_episodes=5",
    )


@pytest.fixture(scope="session")
def halfcheetah_run(tmp_path_factory) -> Path:
    """HalfCheetah, 1 generation of 2 (the smallest real run: 3 episodes of 1000 steps)."""
    return train(
        tmp_path_factory.mktemp("runs") / "halfcheetah",
        "env=halfcheetah", "algo.generations=1", "algo.population=2", "algo.elite_candidates=1", "algo.elite_episodes=1",
    )
