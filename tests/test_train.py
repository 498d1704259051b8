import os
import signal
import subprocess
import time

import pytest
import torch
from conftest import ROOT, TINY, run_train, train_command

from spn_torchrl import checkpoint
from spn_torchrl.records import read_progress, source_commit

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

COLUMNS = [
    "generation",
    "eval_return",
    "best_fitness",
    "mean_fitness",
    "env_steps",
    "total_env_steps",
    "wall_time_s",
    "steps_per_s",
    "mask_density",
    "spike_rate",
]
TIMING = {"wall_time_s", "steps_per_s"}


@pytest.mark.parametrize("algo", ["conn_ga", "weights_ga"])
def test_train_tiny_budget_writes_progress_checkpoint_and_logs(tmp_path, algo):
    run_train(tmp_path, f"algo={algo}", "env=cartpole", *TINY)
    rows = read_progress(tmp_path / "progress.csv")
    assert [r["generation"] for r in rows] == [1, 2]
    assert all(c in rows[0] for c in COLUMNS)
    assert rows[1]["total_env_steps"] == rows[0]["env_steps"] + rows[1]["env_steps"]
    # 10 single episodes + 2 x 5 re-evaluation episodes of at least 8 steps each
    assert all(r["env_steps"] >= 20 * 8 for r in rows)
    assert all(0 <= r["spike_rate"] <= 1 and 0 <= r["mask_density"] <= 1 for r in rows)
    if algo == "weights_ga":
        assert all(r["mask_density"] == 1.0 for r in rows)
    state = checkpoint.load(tmp_path)
    d = 64 * 4 + 2 * 64
    assert state["elites"].shape == (2, d) and state["population"].shape == (10, d)
    assert state["w1"].shape == (64, 4) and state["w2"].shape == (2, 64)
    assert state["generation"] == 2 and state["meta"]["genome"] == ("connections" if algo == "conn_ga" else "weights")
    assert (tmp_path / "logs").is_dir() and (tmp_path / "train.log").exists()
    commit = source_commit()  # this checkout's commit, None while it has uncommitted changes
    recorded = tmp_path / "COMMIT"
    assert (recorded.read_text().strip() if recorded.exists() else None) == commit


def test_killed_run_resumes_to_the_same_result(tmp_path):
    args = [
        "env=cartpole",
        "algo.generations=10",
        "algo.population=20",
        "algo.elite_candidates=2",
        "algo.elite_episodes=5",
        "seed=3",
    ]
    full, killed = tmp_path / "full", tmp_path / "killed"
    run_train(full, *args)

    proc = subprocess.Popen(
        train_command(killed, *args), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    deadline = time.time() + 120
    while len(read_progress(killed / "progress.csv")) < 2 and time.time() < deadline and proc.poll() is None:
        time.sleep(0.02)
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    done_before_kill = len(read_progress(killed / "progress.csv"))
    assert 2 <= done_before_kill < 10, "the run was not killed mid-way"

    run_train(killed, *args, "resume=true")
    a, b = read_progress(full / "progress.csv"), read_progress(killed / "progress.csv")
    assert len(a) == len(b) == 10
    for ra, rb in zip(a, b):
        assert {k: v for k, v in ra.items() if k not in TIMING} == {k: v for k, v in rb.items() if k not in TIMING}
    for scalars in killed.glob("logs/*/scalars/**/*.csv"):  # the CSV logger: each generation once
        steps = [line.split(",")[0] for line in scalars.read_text().splitlines()]
        assert len(steps) == len(set(steps)) == 10, scalars
    sa, sb = checkpoint.load(full), checkpoint.load(killed)
    for key in ("population", "elites", "w1", "w2", "rng"):
        assert torch.equal(sa[key], sb[key]), key
    assert sa["pending"] is None and sb["pending"] is None  # the last re-evaluation ran


def test_resume_with_another_task_fails_clearly(tmp_path):
    run_train(tmp_path, "env=cartpole", *TINY)
    proc = run_train(tmp_path, "env=swimmer", *TINY, "resume=true", check=False)
    assert proc.returncode != 0
    last = proc.stderr.strip().splitlines()[-1]
    assert (
        last.startswith("error:") and "env_id 'CartPole-v1' -> 'Swimmer-v5'" in last and "Traceback" not in proc.stderr
    )
    assert "CartPole-v1" in (tmp_path / ".hydra" / "config.yaml").read_text()  # the run's own record stays


def test_corrupt_checkpoint_fails_clearly(tmp_path):
    run_train(tmp_path, "env=cartpole", *TINY)
    (tmp_path / "checkpoint.pt").write_bytes(b"not a checkpoint")
    proc = run_train(tmp_path, "env=cartpole", *TINY, "resume=true", check=False)
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert "not a readable spn_torchrl checkpoint" in proc.stderr.strip().splitlines()[-1]


def test_existing_run_dir_without_resume_fails_clearly(tmp_path):
    run_train(tmp_path, "env=cartpole", *TINY)
    proc = run_train(tmp_path, "env=cartpole", *TINY, check=False)
    assert proc.returncode != 0 and "resume=true" in proc.stderr.strip().splitlines()[-1]


def test_bad_config_value_fails_before_any_env(tmp_path):
    proc = run_train(tmp_path, "algo.population=7", check=False)
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == "error: algo.population must be even (mirrored pairs), got 7"
    assert not (tmp_path / "progress.csv").exists()


def test_wandb_logger_runs_offline_without_credentials_and_finishes(tmp_path):
    import os
    import subprocess

    env = {k: v for k, v in os.environ.items() if not k.startswith("WANDB_")}
    env["HOME"] = str(tmp_path)  # no netrc: logger.mode=auto must choose offline
    proc = subprocess.run(
        train_command(tmp_path / "run", "env=cartpole", "logger=wandb", *TINY),
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    runs = list((tmp_path / "run" / "wandb").glob("offline-run-*"))
    assert len(runs) == 1 and list(runs[0].glob("*.wandb"))
    assert len(read_progress(tmp_path / "run" / "progress.csv")) == 2
