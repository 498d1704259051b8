"""The run contract, tried as an adversarial user would: a resumed, extended, interrupted or faulty run never gives
a silently different result or loses a file (each case a subprocess run of train.py with a tiny CartPole budget)."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
import yaml
from conftest import ROOT, run_train, train_command, wandb_exit_codes

from spn_torchrl import checkpoint
from spn_torchrl.records import read_progress

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

BASE = ["env=cartpole", "algo.population=20", "algo.elite_candidates=2", "algo.elite_episodes=2", "seed=1"]
TIMING = {"wall_time_s", "steps_per_s"}


def rows(run_dir: Path) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in read_progress(run_dir / "progress.csv")]


def last_line(proc: subprocess.CompletedProcess) -> str:
    return proc.stderr.strip().splitlines()[-1]


@pytest.fixture(scope="module")
def four(tmp_path_factory) -> Path:
    """An uninterrupted 4-generation run: what every repaired or extended run must equal."""
    run_dir = tmp_path_factory.mktemp("contract") / "four"
    run_train(run_dir, *BASE, "algo.generations=4")
    return run_dir


def test_a_resume_that_would_change_results_is_refused_and_the_runs_record_kept(tmp_path):
    run_train(tmp_path, *BASE, "algo.generations=2")
    before = (tmp_path / "progress.csv").read_text()
    changes = ["algo.sigma=0.02", "algo.snn.score_threshold=0.6", "algo.elite_candidates=3", "seed=2"]
    proc = run_train(tmp_path, *BASE, *changes, "algo.generations=3", "resume=true", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    line = last_line(proc)
    assert line.startswith(f"error: resume=true with a config that would change the results of {tmp_path}: ")
    for change in ("algo.sigma 0.01 -> 0.02", "algo.snn.score_threshold 0.5 -> 0.6", "algo.elite_candidates 2 -> 3"):
        assert change in line
    assert "seed 1 -> 2" in line
    assert (tmp_path / "progress.csv").read_text() == before
    saved = yaml.safe_load((tmp_path / ".hydra" / "config.yaml").read_text())
    assert saved["algo"]["sigma"] == 0.01 and saved["seed"] == 1  # the run's own record, not the refused values
    assert checkpoint.load(tmp_path)["config"]["algo"]["sigma"] == 0.01


def test_a_resume_may_change_what_cannot_change_results_and_says_so(tmp_path, four):
    run_train(tmp_path, *BASE, "algo.generations=2")
    run_train(tmp_path, *BASE, "algo.generations=4", "evaluator.processes=1", "logger=csv", "resume=true")
    log = (tmp_path / "train.log").read_text()
    assert "resume: algo.generations 2 -> 4 (does not change results)" in log
    assert "resume: evaluator.processes None -> 1 (does not change results)" in log
    assert "resume: resume " not in log  # resuming is the act, not a change
    assert rows(tmp_path) == rows(four)  # extended: the rows of the uninterrupted 4-generation run


def test_a_directory_with_progress_but_no_checkpoint_is_left_alone(tmp_path):
    tmp_path.mkdir(exist_ok=True)
    (tmp_path / "progress.csv").write_text("generation,eval_return\n1,5.0\n")
    for resume in ("resume=false", "resume=true"):
        proc = run_train(tmp_path, *BASE, "algo.generations=2", resume, check=False)
        assert proc.returncode == 1 and "holds progress.csv but no checkpoint.pt" in last_line(proc)
        assert (tmp_path / "progress.csv").read_text() == "generation,eval_return\n1,5.0\n"


def test_a_deleted_progress_file_is_restored_from_the_checkpoint(tmp_path, four):
    run_train(tmp_path, *BASE, "algo.generations=2")
    (tmp_path / "progress.csv").unlink()
    run_train(tmp_path, *BASE, "algo.generations=4", "resume=true")
    assert rows(tmp_path) == rows(four)


def test_resuming_a_finished_run_says_so_and_changes_nothing(tmp_path):
    run_train(tmp_path, *BASE, "algo.generations=2")
    before = (tmp_path / "progress.csv").read_text()
    proc = run_train(tmp_path, *BASE, "algo.generations=2", "resume=true")
    assert "already ran its 2 generations" in (tmp_path / "train.log").read_text() + proc.stderr
    assert (tmp_path / "progress.csv").read_text() == before
    proc = run_train(tmp_path, *BASE, "algo.generations=1", "resume=true", check=False)
    assert last_line(proc) == f"error: algo.generations=1 is below the 2 generations {tmp_path} has done"


@pytest.mark.parametrize("sig,code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_a_signal_leaves_a_consistent_checkpoint_and_one_line(tmp_path, four, sig, code):
    proc = subprocess.Popen(
        train_command(tmp_path, *BASE, "algo.generations=4", "algo.population=200", "algo.elite_episodes=10"),
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    deadline = time.time() + 120
    while not (tmp_path / "checkpoint.pt").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    assert "Traceback" not in err
    line = err.strip().splitlines()[-1]
    assert line.startswith(
        f"stopped: interrupted by {sig.name}; {tmp_path} holds a consistent checkpoint, resume with:"
    )
    assert f"hydra.run.dir={tmp_path} resume=true" in line
    state = checkpoint.load(tmp_path)
    assert len(state["rows"]) == len(read_progress(tmp_path / "progress.csv"))


def test_a_signalled_run_resumes_to_the_uninterrupted_result(tmp_path, four):
    proc = subprocess.Popen(
        train_command(tmp_path, *BASE, "algo.generations=4"),
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    deadline = time.time() + 120
    while not read_progress(tmp_path / "progress.csv") and time.time() < deadline and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    proc.communicate(timeout=120)
    state = checkpoint.load(tmp_path)
    run_train(tmp_path, *BASE, "algo.generations=4", "resume=true")
    assert rows(tmp_path) == rows(four)
    done, pending = state["generation"], state["pending"] is not None
    if pending:  # stopped between a generation's evaluation and its elite's re-evaluation: its row is not yet written
        said = f"resuming {tmp_path} after generation {done}; its row follows its elite's re-evaluation"
        assert len(state["rows"]) == done - 1
    else:
        said = f"resuming {tmp_path} after generation {done}\n" if done < 4 else "already ran its 4 generations"
        assert len(state["rows"]) == done
    assert said in (tmp_path / "train.log").read_text()


def test_file_faults_are_one_sentence(tmp_path):
    logs_file = tmp_path / "logs_file"
    logs_file.mkdir()
    (logs_file / "logs").write_text("not a directory")
    proc = run_train(logs_file, *BASE, "algo.generations=1", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert last_line(proc).startswith(f"error: {logs_file / 'logs'} is a file, expected a directory")

    run_dir = tmp_path / "progress_dir"
    run_train(run_dir, *BASE, "algo.generations=1")
    (run_dir / "progress.csv").unlink()
    (run_dir / "progress.csv").mkdir()
    proc = run_train(run_dir, *BASE, "algo.generations=2", "resume=true", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert last_line(proc) == f"error: {run_dir / 'progress.csv'} is a directory, expected a file"
    shutil.rmtree(run_dir / "progress.csv")


def test_the_run_contract_is_written_into_every_checkpoint(tmp_path):
    run_train(tmp_path, *BASE, "algo.generations=1")
    state = checkpoint.load(tmp_path)
    assert state["config"]["algo"]["generations"] == 1 and state["config"]["seed"] == 1
    assert [r["generation"] for r in state["rows"]] == [1]


def test_run_files_get_the_umasks_mode(tmp_path):
    umask = os.umask(0o027)
    try:
        run_train(tmp_path, *BASE, "algo.generations=1")
    finally:
        os.umask(umask)
    for name in ("progress.csv", "checkpoint.pt"):
        assert (tmp_path / name).stat().st_mode & 0o777 == 0o640, name


PPO = ["algo=dpn_ppo", "algo.frames_per_batch=200", "algo.minibatch_size=50", "algo.epochs=2", "algo.eval_episodes=2"]


@pytest.mark.parametrize("method", [BASE + ["algo.generations=50", "algo.population=200"], PPO + ["env=cartpole"]])
def test_a_stopped_run_is_marked_in_wandb_for_the_ga_and_ppo(tmp_path, method):
    env = {k: v for k, v in os.environ.items() if not k.startswith("WANDB_")}
    env.update(HOME=str(tmp_path), WANDB_SILENT="true")
    run_dir = tmp_path / "run"
    proc = subprocess.Popen(
        train_command(run_dir, *method, "logger=wandb"),
        cwd=ROOT,
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    deadline = time.time() + 180
    while not (run_dir / "checkpoint.pt").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=180)
    assert proc.returncode == 143 and b"Traceback" not in err
    assert wandb_exit_codes(run_dir) == [143]
