"""The report groups by what changes results (issue 44): the task is env.id, a seed run twice counts once, and runs of
one method with different results-affecting configs are listed apart."""

from __future__ import annotations

import copy
import json
import shutil
import subprocess
import sys

import pytest
from conftest import ROOT, run_train
from omegaconf import OmegaConf
from synthetic_runs import write_run

from spn_torchrl.analysis.report import build_report
from spn_torchrl.config import config_dict


def set_field(run, key, value):
    path = run / ".hydra/config.yaml"
    config = OmegaConf.load(path)
    OmegaConf.update(config, key, value)
    path.write_text(OmegaConf.to_yaml(config))


def test_a_copied_seed_counts_once_and_is_named(tmp_path):
    for seed in (0, 1):
        write_run(tmp_path / "a", "cartpole", "CartPole-v1", "conn_ga", seed, [10.0, 20.0 + seed])
    shutil.copytree(tmp_path / "a/cartpole__conn_ga__0", tmp_path / "b/cartpole__conn_ga__0")
    result = build_report([tmp_path], tmp_path / "out")
    method = result["tasks"]["cartpole"]["methods"]["conn_ga"]
    assert method["seeds"] == [0, 1] and method["final_return_std"] == pytest.approx(0.5)
    (repeat,) = result["tasks"]["cartpole"]["duplicates"]["conn_ga"]
    assert repeat["seed"] == 0 and repeat["path"].endswith("b/cartpole__conn_ga__0")
    assert "a seed run more than once counts once" in (tmp_path / "out/report.md").read_text()


def test_runs_with_different_results_affecting_configs_are_listed_apart(tmp_path):
    for seed in (0, 1):
        write_run(tmp_path, "cartpole", "CartPole-v1", "conn_ga", seed, [10.0])
    set_field(tmp_path / "cartpole__conn_ga__1", "algo.sigma", 0.5)
    set_field(tmp_path / "cartpole__conn_ga__1", "evaluator.name", "ray")  # cannot change results: not a split
    set_field(tmp_path / "cartpole__conn_ga__0", "algo.sigma", 0.01)
    methods = build_report([tmp_path], tmp_path / "out")["tasks"]["cartpole"]["methods"]
    assert {name: m["seeds"] for name, m in methods.items()} == {
        "conn_ga (algo.sigma=0.01)": [0],
        "conn_ga (algo.sigma=0.5)": [1],
    }
    assert "different results-affecting configs are listed apart" in (tmp_path / "out/report.md").read_text()


def test_runs_saved_in_an_earlier_schema_pool_with_todays(tmp_path, make_config):
    """A run saved before algo.snn existed (its SNN constants under algo.) and before normalize_observations and
    env.device were added is a seed of the same method as one saved today with the same values."""
    today = config_dict(make_config("env=cartpole"))
    earlier = copy.deepcopy(today)
    earlier["algo"].update(earlier["algo"].pop("snn"))
    del earlier["normalize_observations"], earlier["env"]["device"]
    for seed, config in enumerate((earlier, today)):
        run = write_run(tmp_path, "cartpole", "CartPole-v1", "conn_ga", seed, [10.0 + seed])
        (run / ".hydra/config.yaml").write_text(OmegaConf.to_yaml({**config, "seed": seed}))
    methods = build_report([tmp_path], tmp_path / "out")["tasks"]["cartpole"]["methods"]
    assert {name: m["seeds"] for name, m in methods.items()} == {"conn_ga": [0, 1]}


@pytest.mark.slow
def test_the_task_is_env_id_not_env_name(tmp_path, cartpole_run):
    shutil.copytree(cartpole_run, tmp_path / "runs/cartpole")
    tiny = ["algo.generations=2", "algo.population=10", "algo.elite_candidates=2", "algo.elite_episodes=5"]
    run_train(tmp_path / "runs/pendulum", "env.id=Pendulum-v1", "env.backend=gymnasium", *tiny, "evaluator.processes=1")
    command = [sys.executable, "-m", "spn_torchrl.report", str(tmp_path / "runs"), "--out", str(tmp_path / "out")]
    subprocess.run(command, cwd=ROOT, check=True, capture_output=True, timeout=600)
    tasks = json.loads((tmp_path / "out/report.json").read_text())
    assert {name: t["env_id"] for name, t in tasks.items()} == {
        "cartpole__CartPole-v1": "CartPole-v1",
        "cartpole__Pendulum-v1": "Pendulum-v1",
    }
    assert all(t["methods"]["conn_ga"]["seeds"] == [0] for t in tasks.values())
