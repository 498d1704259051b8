"""GA runs in lockstep (``lockstep=[seeds]``): each run writes the rows of its separate run, bit for bit, on the CPU
backends, and keeps the run contract (resume, extension alone or in lockstep, signals, its own W&B run)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import yaml
from conftest import ROOT, run_train, train_command

from spn_torchrl import checkpoint
from spn_torchrl.errors import ConfigError
from spn_torchrl.records import read_progress

CARTPOLE = ["env=cartpole", "algo.population=20", "algo.elite_candidates=2", "algo.elite_episodes=2"]
TIMING = {"wall_time_s", "steps_per_s"}  # what a lockstep run may write differently: its wall time and speed


def rows(run_dir: Path) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in read_progress(run_dir / "progress.csv")]


def member(lockstep_dir: Path, seed: int, env: str = "cartpole") -> Path:
    return lockstep_dir / f"{env}__conn_ga__{seed}"


@pytest.fixture(scope="module")
def separate(tmp_path_factory) -> dict[int, Path]:
    """Separate uninterrupted 4-generation CartPole runs of seeds 1 and 2: what every lockstep run must equal."""
    root = tmp_path_factory.mktemp("separate")
    for seed in (1, 2):
        run_train(root / str(seed), *CARTPOLE, "algo.generations=4", f"seed={seed}")
    return {seed: root / str(seed) for seed in (1, 2)}


def test_lockstep_seeds_are_checked_before_anything_runs(make_config):
    assert make_config("lockstep=[3,1]").lockstep == [3, 1]
    assert make_config("algo=conn_ec", "normalize_observations=true", "lockstep=[0,1]").lockstep == [0, 1]
    bad = {
        "lockstep=[]": "lockstep must be null or a non-empty list of seeds",
        "lockstep=[1,1]": "lockstep must be a list of distinct seeds",
        "lockstep=[-1]": "lockstep seeds must be an integer in",
        "seed=3 lockstep=[1,2]": r"seed must be 0 \(its default\) with lockstep",
    }
    for override, sentence in bad.items():
        with pytest.raises(ConfigError, match=sentence):
            make_config(*override.split())
    with pytest.raises(ConfigError, match="lockstep must be null for algo=dpn_ppo"):
        make_config("algo=dpn_ppo", "lockstep=[0,1]")


@pytest.mark.slow
def test_cartpole_runs_in_lockstep_write_their_separate_runs_rows(tmp_path, separate):
    run_train(tmp_path, *CARTPOLE, "algo.generations=4", "lockstep=[1,2]")
    for seed, alone in separate.items():
        run_dir = member(tmp_path, seed)
        assert rows(run_dir) == rows(alone) and len(rows(run_dir)) == 4
        mine, theirs = checkpoint.load(run_dir), checkpoint.load(alone)
        for key in ("population", "w1", "w2", "elites"):
            assert mine[key].equal(theirs[key]), key
        assert mine["rng"].equal(theirs["rng"])
        drop = ("logger", "run_name")  # the W&B group and name of a lockstep run: fields that cannot change results
        assert {k: v for k, v in mine["config"].items() if k not in drop} == {
            k: v for k, v in theirs["config"].items() if k not in drop
        }
        # COMMIT as a separate run writes it (written from a clean checkout, as in CI; absent from a dirty one)
        commits = [(d / "COMMIT").read_text() if (d / "COMMIT").exists() else None for d in (run_dir, alone)]
        assert commits[0] == commits[1]
        saved = yaml.safe_load((run_dir / ".hydra" / "config.yaml").read_text())
        assert saved["seed"] == seed and saved["lockstep"] is None  # found by the analysis tools as any run


@pytest.mark.slow
def test_a_mujoco_task_in_lockstep_writes_its_separate_runs_rows(tmp_path):
    swimmer = ["env=swimmer", "algo.generations=2", "algo.population=4", "algo.elite_candidates=1"]
    swimmer.append("algo.elite_episodes=2")
    run_train(tmp_path / "lockstep", *swimmer, "lockstep=[0,5]")
    for seed in (0, 5):
        run_train(tmp_path / str(seed), *swimmer, f"seed={seed}")
        assert rows(member(tmp_path / "lockstep", seed, "swimmer")) == rows(tmp_path / str(seed))


@pytest.mark.slow
def test_lockstep_runs_extend_alone_or_together_to_the_uninterrupted_rows(tmp_path, separate):
    run_train(tmp_path, *CARTPOLE, "algo.generations=2", "lockstep=[1,2]")
    # seed 1 extended alone to 3 generations, as a separate run in its own directory
    run_train(member(tmp_path, 1), *CARTPOLE, "algo.generations=3", "seed=1", "resume=true")
    # then both in lockstep to 4: seed 1 from generation 3, seed 2 from generation 2, sharing rollouts
    proc = run_train(tmp_path, *CARTPOLE, "algo.generations=4", "lockstep=[1,2]", "resume=true")
    log = (tmp_path / "train.log").read_text() + proc.stderr
    assert f"resuming {member(tmp_path, 1)} after generation 3" in log
    assert f"resuming {member(tmp_path, 2)} after generation 2" in log
    for seed, alone in separate.items():
        assert rows(member(tmp_path, seed)) == rows(alone)
    proc = run_train(tmp_path, *CARTPOLE, "algo.generations=4", "lockstep=[1,2]", "resume=true")
    assert "already ran its 4 generations" in (tmp_path / "train.log").read_text() + proc.stderr


@pytest.mark.slow
def test_a_signalled_lockstep_leaves_every_run_consistent_and_resumes_to_the_uninterrupted_rows(tmp_path, separate):
    command = train_command(tmp_path, *CARTPOLE, "algo.generations=4", "lockstep=[1,2]", "algo.population=200")
    proc = subprocess.Popen(command, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    deadline = time.time() + 120
    while not (member(tmp_path, 2) / "checkpoint.pt").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.01)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 143 and "Traceback" not in err, err
    line = err.strip().splitlines()[-1]
    assert line.startswith(f"stopped: interrupted by SIGTERM; {tmp_path} holds a consistent checkpoint, resume with:")
    states = [checkpoint.load(member(tmp_path, seed)) for seed in (1, 2)]
    assert states[0]["generation"] == states[1]["generation"]  # no run saved a rollout the other did not
    for seed, state in zip((1, 2), states):
        assert len(state["rows"]) == len(read_progress(member(tmp_path, seed) / "progress.csv"))
    run_train(tmp_path, *CARTPOLE, "algo.generations=4", "lockstep=[1,2]", "algo.population=200", "resume=true")
    for seed in (1, 2):
        alone = tmp_path.parent / f"alone{seed}"
        run_train(alone, *CARTPOLE, "algo.generations=4", "algo.population=200", f"seed={seed}")
        assert rows(member(tmp_path, seed)) == rows(alone)


@pytest.mark.slow
def test_each_lockstep_run_has_its_own_wandb_run(tmp_path):
    env = {k: v for k, v in os.environ.items() if not k.startswith("WANDB_")}
    env.update(HOME=str(tmp_path), WANDB_SILENT="true", WANDB_MODE="offline")
    command = train_command(tmp_path / "runs", *CARTPOLE, "algo.generations=1", "lockstep=[1,2]", "logger=wandb")
    proc = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    ids = set()
    for seed in (1, 2):
        run_dir = member(tmp_path / "runs", seed)
        (offline,) = run_dir.glob("wandb/offline-run-*")
        ids.add(checkpoint.load(run_dir)["wandb_id"])
        assert offline.name.endswith(checkpoint.load(run_dir)["wandb_id"])
    assert len(ids) == 2


@pytest.mark.slow
def test_a_multirun_over_lockstep_batches_gives_each_batch_its_own_directory(tmp_path, separate):
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    command = [sys.executable, str(ROOT / "train.py"), "-m", f"hydra.sweep.dir={tmp_path}", *CARTPOLE]
    command += ["algo.generations=1", "lockstep=[1,2],[3]"]
    proc = subprocess.run(command, cwd=ROOT, env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert sorted(p.name for p in tmp_path.iterdir() if p.is_dir()) == [
        "cartpole__conn_ga__1-2",
        "cartpole__conn_ga__3",
    ]
    for seed in (1, 2):
        assert rows(member(tmp_path / "cartpole__conn_ga__1-2", seed)) == rows(separate[seed])[:1]
    assert len(rows(member(tmp_path / "cartpole__conn_ga__3", 3))) == 1


@pytest.mark.slow
def test_ec_runs_with_normalised_observations_in_lockstep_write_their_separate_runs_rows_and_statistics(tmp_path):
    ec = ["env=cartpole", "algo=conn_ec", "algo.population=20", "algo.elite_episodes=2", "algo.generations=3"]
    ec.append("normalize_observations=true")
    run_train(tmp_path / "lockstep", *ec, "lockstep=[1,2]")
    for seed in (1, 2):
        run_train(tmp_path / str(seed), *ec, f"seed={seed}")
        mine, theirs = tmp_path / "lockstep" / f"cartpole__conn_ec__{seed}", tmp_path / str(seed)
        assert rows(mine) == rows(theirs) and len(rows(mine)) == 3
        a, b = checkpoint.load(mine), checkpoint.load(theirs)
        for key in ("p", "population", "elites", "elite_norms"):
            assert a[key].equal(b[key]), key
        assert a["adam"]["m"].equal(b["adam"]["m"]) and a["adam"]["v"].equal(b["adam"]["v"])
        assert all(a["obs_stats"][k].equal(b["obs_stats"][k]) for k in ("mean", "summed_variance", "std"))


@pytest.mark.slow
def test_a_lockstep_run_whose_directory_is_locked_is_refused_before_anything_runs(tmp_path):
    import fcntl

    run_dir = member(tmp_path, 2)
    run_dir.mkdir(parents=True)
    with open(run_dir / ".lock", "w") as held:
        fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        proc = run_train(tmp_path, *CARTPOLE, "algo.generations=1", "lockstep=[1,2]", check=False)
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert f"{run_dir} is in use by a live run" in proc.stderr.strip().splitlines()[-1]
    assert not (run_dir / "checkpoint.pt").exists() and not (member(tmp_path, 1) / "checkpoint.pt").exists()
