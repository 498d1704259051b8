"""The report over real tiny CartPole runs (a train.py multirun, two seeds) and a PPO fixture."""

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from synthetic_runs import write_run

from spn_torchrl.analysis.report import build_report
from spn_torchrl.analysis.stats import p_text, welch

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def multirun(tmp_path_factory) -> Path:
    """Two real Connections-GA runs on CartPole at the smoke budget."""
    sweep = tmp_path_factory.mktemp("runs") / "multirun"
    cmd = [
        sys.executable,
        "train.py",
        "-m",
        "+experiment=smoke",
        "seed=0,1",
        "algo.generations=3",
        f"hydra.sweep.dir={sweep}",
    ]
    subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True, timeout=300)
    return sweep


def write_ppo_fixture(root: Path, final_return: float) -> Path:
    """FIXTURE, not a real run: a dpn_ppo run directory written by hand in the PPO progress.csv format
    (iteration, total_env_steps, eval_return, cumulative policy/value forward and backward counts)."""
    run = root / "cartpole__dpn_ppo__0"
    (run / ".hydra").mkdir(parents=True)
    (run / ".hydra" / "config.yaml").write_text(
        "algo:\n  name: dpn_ppo\n  kind: ppo\nenv:\n  name: cartpole\n  id: CartPole-v1\nseed: 0\n"
    )
    fields = [
        "iteration",
        "total_env_steps",
        "eval_return",
        "policy_forward",
        "policy_backward",
        "value_forward",
        "value_backward",
    ]
    with open(run / "progress.csv", "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(fields)
        for it in (1, 2):
            steps = 1000 * it
            writer.writerow([it, steps, final_return / (3 - it), steps * 26, steps * 25, steps * 26, steps * 25])
    return run


def csv_rows(multirun: Path) -> list[list[dict]]:
    runs = sorted(p.parent for p in multirun.rglob("progress.csv"))
    assert len(runs) == 2
    out = []
    for run in runs:
        with open(run / "progress.csv") as f:
            out.append([{k: float(v) for k, v in row.items()} for row in csv.DictReader(f)])
    return out


def test_report_cli_over_a_multirun(multirun, tmp_path):
    """The command writes report.md, report.json, the figure, and (--wandb, offline here) a W&B run."""
    out = tmp_path / "report"
    env = dict(os.environ, WANDB_MODE="offline", WANDB_SILENT="true")
    cmd = [sys.executable, "-m", "spn_torchrl.report", str(multirun), "--out", str(out), "--wandb"]
    subprocess.run(cmd, cwd=ROOT, env=env, check=True, timeout=180)
    assert list((out / "wandb").glob("offline-run-*"))
    md = (out / "report.md").read_text()
    assert (out / "cartpole.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "No PPO run found" in md and "PPO level R: none" in md
    assert "(not the paper's: generations, population, elite_candidates, elite_episodes)" in md
    data = json.loads((out / "report.json").read_text())["cartpole"]

    rows = csv_rows(multirun)
    final = np.array([r[-1]["eval_return"] for r in rows])
    method = data["methods"]["conn_ga"]
    assert method["seeds"] == [0, 1] and method["rows"] == 3
    assert method["final_return_mean"] == pytest.approx(final.mean())
    assert f"{final.mean():.2f} +- {final.std():.2f}" in md

    rate = np.mean([r[-1]["spike_rate"] for r in rows])
    syn1 = np.mean([r[-1]["synapses_l1"] for r in rows])
    syn2 = np.mean([r[-1]["synapses_l2"] for r in rows])
    infer = data["inference"]["conn_ga"]
    assert infer["rate_per_sim_step"] == pytest.approx(rate)
    assert infer["rate_per_env_step"] == pytest.approx(4 * rate)
    assert infer["e_dpn"] == pytest.approx((4 * 64 + 64 * 2) * 4.6)
    assert infer["e_spn_dense"] == pytest.approx(4 * 64 * 4.6 + rate * 64 * 2 * 0.9)
    assert infer["e_spn_mask"] == pytest.approx(syn1 * 4.6 + rate * syn2 * 0.9)
    assert infer["e_spn_mask"] < infer["e_spn_dense"]  # about half the connections exist

    steps = np.mean([r[-1]["total_env_steps"] for r in rows])
    optim = data["optim"]["conn_ga"]
    assert optim["env_steps"] == pytest.approx(steps)
    assert optim["e_ga_dense"] == pytest.approx(infer["e_spn_dense"] * steps)
    assert "not measured" in data["ppo"]["source"]


def test_data_efficiency_at_a_given_ppo_level(multirun, tmp_path):
    rows = csv_rows(multirun)
    curve = np.mean([[row["eval_return"] for row in r] for r in rows], axis=0)
    level = float(curve[1])  # the mean curve reaches it at generation 2 at the latest
    expected_g = int(np.argmax(curve >= level)) + 1
    result = build_report([multirun], tmp_path, level=level)
    eff = result["tasks"]["cartpole"]["data_efficiency"]["conn_ga"]
    assert eff["G"] == expected_g
    used = np.mean([r[expected_g - 1]["total_env_steps"] for r in rows])
    assert eff["E"] == pytest.approx(used)
    assert eff["gamma"] == pytest.approx(used / 1e6)
    assert result["tasks"]["cartpole"]["optim"]["conn_ga"]["env_steps"] == pytest.approx(used)
    unreachable = build_report([multirun], tmp_path / "hi", level=1e9)["tasks"]["cartpole"]["data_efficiency"][
        "conn_ga"
    ]
    assert unreachable["G"] is None and "not reached" in (tmp_path / "hi" / "report.md").read_text()


def test_ppo_runs_set_the_level_and_the_ppo_energy(multirun, tmp_path):
    fixture = write_ppo_fixture(tmp_path / "ppo_fixture", final_return=150.0)
    result = build_report([multirun, fixture.parent], tmp_path / "out")
    task = result["tasks"]["cartpole"]
    assert task["ppo_level"] == pytest.approx(150.0)
    assert "dpn_ppo" in task["methods"] and task["methods"]["dpn_ppo"]["kind"] == "ppo"
    e_dpn, e_dvn = (4 * 64 + 64 * 2) * 4.6, (4 * 64 + 64) * 4.6
    assert task["ppo"]["e_ppo"] == pytest.approx((e_dpn + e_dvn) * 2000 * (26 + 25))
    assert task["ppo"]["env_steps"] == 2000
    assert "No PPO run found" not in (tmp_path / "out" / "report.md").read_text()


def test_runs_logged_to_wandb_send_the_report_there(multirun, tmp_path):
    copy = tmp_path / "runs"
    shutil.copytree(multirun, copy)
    assert build_report([copy], tmp_path / "a")["wandb_projects"] == []
    for config in copy.rglob(".hydra/config.yaml"):
        config.write_text(
            config.read_text().replace("backend: csv\n  project: spn_torchrl", "backend: wandb\n  project: my_proj")
        )
    assert build_report([copy], tmp_path / "b")["wandb_projects"] == ["my_proj"]


def test_methods_of_a_task_are_tested_against_each_other(tmp_path):
    """Welch's test of each pair of methods with 2 seeds or more (conn_ec's single seed makes no pair)."""
    ga, weights = [100.0, 110.0, 120.0], [150.0, 170.0, 160.0]
    for seed in range(3):
        write_run(tmp_path / "runs", "cartpole", "CartPole-v1", "conn_ga", seed, [1.0, ga[seed]])
        write_run(tmp_path / "runs", "cartpole", "CartPole-v1", "weights_ga", seed, [1.0, weights[seed]])
    write_run(tmp_path / "runs", "cartpole", "CartPole-v1", "conn_ec", 0, [1.0, 300.0])
    md = Path(build_report([tmp_path / "runs"], tmp_path / "out")["markdown"]).read_text()
    p = welch(110.0, 10.0, 3, 160.0, 10.0, 3).p
    assert f"| conn_ga vs weights_ga | 3 / 3 | 110.00 - 160.00 = -50.00 | {p_text(p)} |" in md
    assert "conn_ec vs" not in md and "vs conn_ec" not in md


def test_ec_runs_get_the_ga_tables_and_a_preface_heads_the_report(tmp_path):
    """conn_ec is an evolved SPN like the GA: its data efficiency, inference and optimisation energy rows are
    computed the same way; a PREFACE.md in --out is the report's top, verbatim."""
    for seed in range(2):
        write_run(tmp_path / "runs", "cartpole", "CartPole-v1", "conn_ga", seed, [10.0, 50.0, 100.0 + seed])
        write_run(tmp_path / "runs", "cartpole", "CartPole-v1", "conn_ec", seed, [10.0, 90.0, 120.0 + seed], kind="ec")
    out = tmp_path / "out"
    out.mkdir()
    (out / "PREFACE.md").write_text("# Beyond the paper\n\nHand-written.\n")
    result = build_report([tmp_path / "runs"], out, level=80.0)
    md = Path(result["markdown"]).read_text()
    assert md.startswith("# Beyond the paper\n\nHand-written.\n\n# SPN report")
    s = result["tasks"]["cartpole"]
    assert set(s["inference"]) == set(s["optim"]) == set(s["data_efficiency"]) == {"conn_ga", "conn_ec"}
    assert s["data_efficiency"]["conn_ec"]["G"] == 2 and s["data_efficiency"]["conn_ga"]["G"] == 3
    assert s["optim"]["conn_ec"]["env_steps"] == 2000.0  # env steps up to G, as the GA's
    assert "| conn_ec | 0.1000 |" in md  # its inference energy row
    assert "| conn_ec vs conn_ga | 2 / 2 |" in md
