"""README's sweep through ``hydra/launcher=slurm`` on a real single-node Slurm cluster (``.ci/slurm.sh start``):
two seeds each write their run; a job that fails and one cancelled with ``scancel`` end the sweep with one
sentence naming each; ``resume=true`` then finishes the cancelled run with the rows of an uninterrupted one."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from conftest import ROOT, wandb_exit_codes

from spn_torchrl.records import read_progress

pytestmark = [pytest.mark.slow, pytest.mark.slurm]

TIMING = {"wall_time_s", "steps_per_s"}
# 30 CartPole generations of 10: long enough (seconds) for scancel to land inside the run
SWEEP = [
    "hydra/launcher=slurm",
    "hydra.launcher.cpus_per_task=1",  # two jobs at once on a 2-CPU node
    "hydra.launcher.timeout_min=10",
    "env=cartpole",
    "algo=conn_ga",
    "algo.generations=30",
    "algo.population=10",
    "algo.elite_candidates=2",
    "torch_threads=1",
    "evaluator.processes=1",
]


def slurm(*args: str) -> str:
    done = subprocess.run(list(args), capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, f"{' '.join(args)} failed: {done.stderr}"
    return done.stdout


@pytest.fixture(scope="module", autouse=True)
def cluster():
    """The cluster must be up: with SPN_TEST_SLURM=1 a missing one fails the tests, it does not skip them."""
    assert "idle" in slurm("sinfo", "-h", "-o", "%T").split(), "no idle Slurm node: start one with .ci/slurm.sh"


def sweep(sweep_dir: Path, *overrides: str, background: bool = False):
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    cmd = [sys.executable, str(ROOT / "train.py"), "-m", f"hydra.sweep.dir={sweep_dir}", *SWEEP, *overrides]
    if background:
        return subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)


def states(job_ids: list[str]) -> dict[str, str]:
    """Each job's state as Slurm's accounting (sacct) records it, without the "by <uid>" of CANCELLED."""
    out = slurm("sacct", "-n", "-X", "-P", "-o", "JobID,State", "-j", ",".join(job_ids))
    return {job: state.split()[0] for job, state, *_ in (line.split("|") for line in out.splitlines() if line)}


def submitted(output: str) -> list[str]:
    return re.findall(r"job (\d+(?:_\d+)?) submitted", output)  # an array's jobs are <id>_<index>, one job <id>


def recorded(run_dir: Path) -> bool:
    """The run has written its first generation's row: train.py's SIGTERM handler is in place."""
    path = run_dir / "progress.csv"
    return path.is_file() and len(path.read_text().splitlines()) >= 2


def rows(run_dir: Path) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in read_progress(run_dir / "progress.csv")]


@pytest.fixture(scope="module")
def two_seeds(tmp_path_factory) -> Path:
    sweep_dir = tmp_path_factory.mktemp("slurm") / "two_seeds"
    done = sweep(sweep_dir, "algo.elite_episodes=5", "seed=0,1")
    assert done.returncode == 0, done.stderr[-3000:]
    jobs = submitted(done.stderr + done.stdout)
    print("slurm two seeds:", states(jobs))
    assert list(states(jobs).values()) == ["COMPLETED", "COMPLETED"]
    return sweep_dir


def test_a_slurm_sweep_writes_one_run_per_seed(two_seeds):
    for seed in (0, 1):
        run_dir = two_seeds / f"cartpole__conn_ga__{seed}"
        assert [r["generation"] for r in rows(run_dir)] == list(range(1, 31))
        assert (run_dir / "COMMIT").read_text().strip() == slurm("git", "-C", str(ROOT), "rev-parse", "HEAD").strip()
    assert rows(two_seeds / "cartpole__conn_ga__0") != rows(two_seeds / "cartpole__conn_ga__1")


def test_failed_and_cancelled_jobs_are_one_sentence_and_resume_finishes_the_run(two_seeds, tmp_path):
    sweep_dir = tmp_path / "sweep"
    run_dir = sweep_dir / "cartpole__conn_ga__0"
    # job _0 is seed 0 of the two-seed sweep, cancelled while it runs; job _1 fails (an invalid value)
    proc = sweep(sweep_dir, "seed=0", "logger=wandb", "logger.mode=offline", "algo.elite_episodes=5,0", background=True)
    deadline = time.time() + 300
    while not recorded(run_dir) and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    assert recorded(run_dir), "the job to cancel never recorded its first generation"
    (cancel,) = [p.name for p in (sweep_dir / ".submitit").iterdir() if p.name.endswith("_0")]
    slurm("scancel", cancel)  # SIGTERM to every process of the job: train.py's and W&B's service's
    out, err = proc.communicate(timeout=300)
    jobs = submitted(out + err)
    print("slurm failed and cancelled:", states(jobs))
    assert states(jobs) == {cancel: "CANCELLED", jobs[1]: "FAILED"}
    assert proc.returncode == 1 and "Traceback" not in err
    last = err.strip().splitlines()[-1]
    print("the sweep's last line:", last)
    assert last.startswith("error: 2 of 2 Slurm jobs did not complete: ")
    assert f"job {cancel} (" in last and "ended CANCELLED" in last and "stopped: interrupted by SIGTERM" in last
    assert "resume with: python train.py " in last
    assert f"job {jobs[1]} (" in last and "ended FAILED" in last
    assert "algo.elite_episodes must be an integer in [1, 5], got 0" in last
    # W&B's service got the SIGTERM too and dropped the run: the job says so and still ends with its own sentence
    assert "the logger was not closed (exit code 143 not recorded)" in (run_dir / "train.log").read_text()
    assert wandb_exit_codes(run_dir) == []
    assert 1 <= len(rows(run_dir)) < 30

    done = sweep(sweep_dir, "seed=0", "logger=wandb", "logger.mode=offline", "algo.elite_episodes=5", "resume=true")
    assert done.returncode == 0, done.stderr[-3000:]
    (resumed,) = submitted(done.stderr + done.stdout)
    print("slurm resume:", states([resumed]))
    assert states([resumed]) == {resumed: "COMPLETED"}
    assert rows(run_dir) == rows(two_seeds / "cartpole__conn_ga__0")
