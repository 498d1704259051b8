"""algo=conn_ec end to end: train.py in a subprocess writes the GA's rows and checkpoint, and a SIGTERM-stopped or
extended run resumes to the uninterrupted run's rows bit for bit."""

from __future__ import annotations

import pytest
import torch
from conftest import run_train, sigterm_after_first_checkpoint

from spn_torchrl import checkpoint
from spn_torchrl.records import read_progress
from spn_torchrl.tools.elite import load_elite

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

BASE = ["algo=conn_ec", "env=cartpole", "algo.population=20", "algo.elite_episodes=2", "seed=1"]
TIMING = {"wall_time_s", "steps_per_s"}


def rows(run_dir) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in read_progress(run_dir / "progress.csv")]


@pytest.fixture(scope="module")
def four(tmp_path_factory):
    """An uninterrupted 4-generation EC run: what every stopped or extended run must equal."""
    run_dir = tmp_path_factory.mktemp("ec") / "four"
    run_train(run_dir, *BASE, "algo.generations=4")
    return run_dir


def test_a_tiny_run_writes_the_gas_rows_and_ecs_state(four, cartpole_run):
    got = read_progress(four / "progress.csv")
    assert [r["generation"] for r in got] == [1, 2, 3, 4]
    assert list(got[0]) == list(read_progress(cartpole_run / "progress.csv")[0])  # the GA's columns
    assert all(r["elite_index"] == -1 for r in got)  # the deterministic mask, not a sampled individual
    assert got[0]["mask_density"] == 0.0  # p = 0.5 everywhere at generation 1, and the elite is p > 0.5
    assert all(0 < r["mask_density"] < 1 for r in got[1:])
    # each generation: 20 masks of one episode and the elite's 2 episodes; CartPole's return is its steps
    assert all(r["best_fitness"] >= r["mean_fitness"] for r in got)
    assert sum(r["env_steps"] for r in got) == got[-1]["total_env_steps"]
    state = checkpoint.load(four)
    assert state["meta"]["format"] == checkpoint.EC_FORMAT and state["pending"] is None
    assert state["config"]["algo"]["kind"] == "ec" and state["adam"]["t"] == 4
    assert ((state["p"] >= 1e-3) & (state["p"] <= 1 - 1e-3)).all() and not (state["p"] == 0.5).all()
    elite = load_elite(four)  # play and export read an EC run's elites as a GA run's
    x1, x2 = elite.masks
    assert torch.equal(torch.cat([x1.flatten(), x2.flatten()]), state["elites"][-1] > 0)
    assert int(x1.sum()) == got[-1]["synapses_l1"] and int(x2.sum()) == got[-1]["synapses_l2"]


def test_an_extended_run_writes_the_rows_of_the_longer_one(tmp_path, four):
    run_train(tmp_path, *BASE, "algo.generations=2")
    run_train(tmp_path, *BASE, "algo.generations=4", "resume=true")
    assert rows(tmp_path) == rows(four)
    assert torch.equal(checkpoint.load(tmp_path)["p"], checkpoint.load(four)["p"])


def test_a_sigterm_stopped_run_resumes_to_the_uninterrupted_rows(tmp_path, four):
    returncode, err = sigterm_after_first_checkpoint(tmp_path, *BASE, "algo.generations=4")
    state = checkpoint.load(tmp_path)
    assert returncode == 143 and b"holds a consistent checkpoint" in err, err
    assert state["generation"] < 4 or state["pending"] is not None  # stopped before its end
    run_train(tmp_path, *BASE, "algo.generations=4", "resume=true")
    assert rows(tmp_path) == rows(four)
    final = checkpoint.load(tmp_path)
    expected = checkpoint.load(four)
    for key in ("p", "elites", "rng"):
        assert torch.equal(final[key], expected[key]), key
    for key in ("m", "v"):
        assert torch.equal(final["adam"][key], expected["adam"][key]), key


def test_a_resume_that_changes_ecs_update_is_refused(tmp_path):
    run_train(tmp_path, *BASE, "algo.generations=1")
    proc = run_train(tmp_path, *BASE, "algo.generations=2", "algo.lr=0.1", "resume=true", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "algo.lr 0.15 -> 0.1" in proc.stderr.strip().splitlines()[-1]


def test_a_ga_checkpoint_is_not_resumed_as_ec(tmp_path):
    run_train(tmp_path, "env=cartpole", "algo.population=20", "algo.elite_candidates=2", "algo.elite_episodes=2")
    proc = run_train(tmp_path, *BASE, "algo.generations=2", "resume=true", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.strip().splitlines()[-1].startswith("error: ")
