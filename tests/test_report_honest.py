"""An honest report (issue 13, item 7): missing paths are errors, runs that stopped early are listed apart, and a
pooled curve covers only the generations every run it includes reached. Fast: runs written by hand."""

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from synthetic_runs import write_run

from spn_torchrl.analysis.report import build_report
from spn_torchrl.analysis.runs import find_runs, last_value, pooled
from spn_torchrl.errors import SpnError

ROOT = Path(__file__).resolve().parents[1]


def cartpole(root: Path, seed: int, returns, generations=None, **kw) -> Path:
    return write_run(root, "cartpole", "CartPole-v1", "conn_ga", seed, returns, generations, **kw)


def report_cli(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "spn_torchrl.report", *args], cwd=ROOT, capture_output=True, text=True, timeout=300
    )


@pytest.mark.slow  # processes or a CLI in a subprocess
def test_a_missing_path_is_an_error_naming_it(tmp_path):
    missing = tmp_path / "mulitrun"  # mistyped
    with pytest.raises(SpnError, match="mulitrun does not exist"):
        find_runs([missing])
    proc = report_cli(str(missing), "--out", str(tmp_path / "out"))
    assert proc.returncode != 0
    assert proc.stderr.strip() == f"error: {missing} does not exist"
    assert "Traceback" not in proc.stderr and not (tmp_path / "out").exists()


def test_a_path_without_runs_is_an_error(tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(SpnError, match="no run found under"):
        build_report([tmp_path / "empty"], tmp_path / "out")


def test_a_run_that_stopped_early_is_listed_apart_not_pooled(tmp_path):
    rng = np.random.default_rng(0)
    finished = rng.uniform(0, 500, 30)
    cartpole(tmp_path, 0, finished)
    cartpole(tmp_path, 1, [1.0, 2.0, 3.0], generations=30)  # stopped at generation 3 of 30
    result = build_report([tmp_path], tmp_path / "out")
    method = result["tasks"]["cartpole"]["methods"]["conn_ga"]
    assert method["seeds"] == [0] and method["rows"] == 30 and method["finished"]
    assert method["final_return_mean"] == pytest.approx(finished[-1])
    assert [(e["seed"], e["progress"]) for e in method["left_out"]] == [(1, "3 of 30 generations")]
    md = (tmp_path / "out" / "report.md").read_text()
    assert "conn_ga seed 1: 3 of 30 generations" in md
    assert "conn_ga: left out (stopped before their budget): seed 1 (3 of 30 generations); pooled: seeds [0]." in md
    assert result["stopped"][0]["seed"] == 1
    assert json.loads((tmp_path / "out" / "report.json").read_text())["cartpole"]["methods"]["conn_ga"]["rows"] == 30


def test_with_no_finished_run_the_curve_covers_the_generations_all_reached(tmp_path):
    cartpole(tmp_path, 0, [10.0, 20.0, 30.0], generations=30)
    cartpole(tmp_path, 1, [11.0, 21.0, 31.0, 41.0, 51.0], generations=30)
    result = build_report([tmp_path], tmp_path / "out")
    method = result["tasks"]["cartpole"]["methods"]["conn_ga"]
    assert method["rows"] == 3 and not method["finished"] and method["seeds"] == [0, 1]
    assert method["final_return_mean"] == pytest.approx(30.5)
    assert [e["progress"] for e in method["unfinished_pooled"]] == ["3 of 30 generations", "5 of 30 generations"]
    md = (tmp_path / "out" / "report.md").read_text()
    assert "**conn_ga: no run reached its budget**" in md and "over the 3 generations all of them" in md


@pytest.mark.slow  # processes or a CLI in a subprocess
def test_cli_names_the_runs_that_stopped_early(tmp_path):
    cartpole(tmp_path, 0, [5.0, 6.0])
    cartpole(tmp_path, 1, [5.0], generations=2)
    proc = report_cli(str(tmp_path), "--out", str(tmp_path / "out"))
    assert proc.returncode == 0, proc.stderr
    assert "cartpole conn_ga seed 1: 1 of 2 generations" in proc.stdout


def test_both_config_layouts_and_both_snn_schemas_are_read(tmp_path):
    cartpole(tmp_path, 0, [1.0, 2.0], layout="hydra")
    cartpole(tmp_path, 1, [3.0, 4.0], layout="flat", snn_schema="new")
    runs = find_runs([tmp_path])
    assert [r.seed for r in runs] == [0, 1] and all(r.finished for r in runs)
    assert runs[1].snn("hidden", 0) == 64 and runs[1].snn("time_steps", 0) == 4
    assert runs[0].snn("hidden", 0) == 64 and runs[0].snn("decay", 0.75) == 0.75


def test_pooled_and_last_values_stop_at_the_common_row(tmp_path):
    cartpole(tmp_path, 0, [1.0, 2.0, 3.0])
    cartpole(tmp_path, 1, [10.0, 20.0])
    runs = find_runs([tmp_path])
    assert pooled(runs, "eval_return").shape == (2, 2)
    assert last_value(runs, "eval_return") == pytest.approx((2.0 + 20.0) / 2)


def test_ppo_runs_are_finished_at_their_env_step_budget(tmp_path):
    done = write_run(tmp_path, "cartpole", "CartPole-v1", "dpn_ppo", 0, [1, 2], kind="ppo", total_env_steps=2000)
    short = write_run(tmp_path, "cartpole", "CartPole-v1", "dpn_ppo", 1, [1, 2], kind="ppo", total_env_steps=5000)
    runs = {r.path: r for r in find_runs([tmp_path])}
    assert runs[done.resolve()].finished
    assert not runs[short.resolve()].finished
    assert runs[short.resolve()].progress_text == "2000 of 5000 env steps"
