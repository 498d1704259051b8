"""How tests run train.py (in a subprocess, as a user would), and tiny real runs shared by several tests."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from omegaconf import DictConfig

from spn_torchrl.config import RunConfig, register_configs, to_run_config

ROOT = Path(__file__).resolve().parents[1]
CONF = ROOT / "conf"
register_configs()
TINY = ["algo.generations=2", "algo.population=10", "algo.elite_candidates=2", "algo.elite_episodes=5"]


def compose_config(*overrides: str) -> DictConfig:
    """conf/config.yaml composed with ``overrides`` through Hydra's Compose API, as train.py composes it."""
    with initialize_config_dir(config_dir=str(CONF), version_base=None):
        return compose(config_name="config", overrides=list(overrides))


@pytest.fixture
def make_config():
    """The typed, validated run config of some overrides (what ``run()`` receives after composition)."""

    def make(*overrides: str) -> RunConfig:
        return to_run_config(compose_config(*overrides))

    return make


def train_command(run_dir: Path, *overrides: str) -> list[str]:
    return [sys.executable, str(ROOT / "train.py"), f"hydra.run.dir={run_dir}", *overrides]


def run_train(run_dir: Path, *overrides: str, check: bool = True) -> subprocess.CompletedProcess:
    """Run train.py into ``run_dir``; with ``check``, fail the test with its output if it fails."""
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    # a guard against a hung run, not a speed check: a tiny HumanoidStandup run on Warp's cpu device took 588 s on
    # a slow 2-core host (25% CPU steal) while the suite's other processes ran
    proc = subprocess.run(
        train_command(run_dir, *overrides), cwd=ROOT, env=env, capture_output=True, text=True, timeout=1800
    )
    if check and proc.returncode != 0:
        pytest.fail(f"train.py failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def sigterm_after_first_checkpoint(run_dir: Path, *overrides: str) -> tuple[int, bytes]:
    """Start train.py into ``run_dir``, send it SIGTERM once its first checkpoint exists: its return code and
    stderr."""
    proc = subprocess.Popen(
        train_command(run_dir, *overrides), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    deadline = time.time() + 120
    while not (run_dir / "checkpoint.pt").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    return proc.returncode, err


def wandb_exit_codes(run_dir: Path) -> list[int]:
    """The exit codes an offline W&B run file records (its records are framed as a LevelDB log)."""
    from wandb.proto import wandb_internal_pb2

    (path,) = run_dir.glob("wandb/offline-run-*/*.wandb")
    data, pos, block, pending, codes = path.read_bytes(), 7, 32768, b"", []
    while pos + 7 <= len(data):
        if block - pos % block < 7:  # a block's tail too short for a header is padding
            pos += block - pos % block
            continue
        length, kind = int.from_bytes(data[pos + 4 : pos + 6], "little"), data[pos + 6]
        pending += data[pos + 7 : pos + 7 + length]
        pos += 7 + length
        if kind in (1, 4):  # a full record, or the last piece of one
            record = wandb_internal_pb2.Record()
            record.ParseFromString(pending)
            pending = b""
            if record.HasField("exit"):
                codes.append(record.exit.exit_code)
    return codes


@pytest.fixture(scope="session")
def cartpole_run(tmp_path_factory) -> Path:
    """CartPole, 2 generations of 10 (2 elite candidates x 5 episodes)."""
    run_dir = tmp_path_factory.mktemp("runs") / "cartpole"
    run_train(run_dir, "env=cartpole", *TINY)
    return run_dir


@pytest.fixture(scope="session")
def halfcheetah_run(tmp_path_factory) -> Path:
    """HalfCheetah, 1 generation of 2 (the smallest real run: 3 episodes of 1000 steps)."""
    run_dir = tmp_path_factory.mktemp("runs") / "halfcheetah"
    run_train(
        run_dir,
        "env=halfcheetah",
        "algo.generations=1",
        "algo.population=2",
        "algo.elite_candidates=1",
        "algo.elite_episodes=1",
    )
    return run_dir


# Tests marked ``slurm`` submit jobs to a real Slurm cluster (.ci/slurm.sh starts one). They run when
# SPN_TEST_SLURM=1 (.ci/run sets it once its cluster is up, so there a cluster that is not up fails them) and are
# deselected, not skipped, elsewhere.
def pytest_collection_modifyitems(config, items):
    if os.environ.get("SPN_TEST_SLURM") == "1":
        return
    deselected = [item for item in items if item.get_closest_marker("slurm")]
    if deselected:
        config.hook.pytest_deselected(items=deselected)
        items[:] = [item for item in items if not item.get_closest_marker("slurm")]
