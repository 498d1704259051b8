"""Our seeds against the authors' per-seed logs: synthetic runs and a synthetic log (never the reference files)."""

import csv
from pathlib import Path

import numpy as np
import pytest
from synthetic_runs import write_run

from spn_torchrl.analysis.by_generation import by_generation, main, read_reference, reference_path
from spn_torchrl.analysis.stats import welch
from spn_torchrl.errors import SpnError

PAPER = {10: [100.0, 200.0, 300.0], 20: [120.0, 260.0, 310.0], 30: [80.0, 100.0, 400.0]}
OURS = {0: [90.0, 150.0, 250.0], 1: [110.0, 210.0, 330.0]}


def write_reference(folder: Path, env_id: str = "Swimmer-v2", variant: str = "Connections", seeds=PAPER) -> Path:
    """A log in the authors' layout: generation, seed_S..., mean, std_pop."""
    folder.mkdir(exist_ok=True)
    path = folder / f"{env_id}_SPN_{variant}_elite_returns_by_gen.csv"
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["generation", *(f"seed_{s}" for s in seeds), "mean", "std_pop"])
        for g in range(len(next(iter(seeds.values())))):
            values = [v[g] for v in seeds.values()]
            writer.writerow([g + 1, *values, np.mean(values), np.std(values)])
    return path


@pytest.fixture
def runs(tmp_path) -> Path:
    for seed, returns in OURS.items():
        write_run(tmp_path / "runs", "swimmer", "Swimmer-v5", "conn_ga", seed, returns)
    write_run(tmp_path / "runs", "swimmer", "Swimmer-v5", "conn_ga", 7, [1e6], generations=3)  # stopped: left out
    return tmp_path / "runs"


def test_reference_is_read_by_seed_column(tmp_path):
    curves = read_reference(write_reference(tmp_path / "ref"))
    assert curves.seeds == [10, 20, 30]
    np.testing.assert_array_equal(curves.returns, np.array(list(PAPER.values())))
    assert reference_path("R", "humanoidstandup", "weights_ga").name == (
        "HumanoidStandup-v2_SPN_Weights_elite_returns_by_gen.csv"
    )


def test_table_holds_means_sample_stds_ratios_and_welch(runs, tmp_path):
    write_reference(tmp_path / "ref")
    text = by_generation([runs], tmp_path / "ref", "swimmer", generations=[1, 3, 50], level=200.0)
    lines = text.splitlines()
    assert lines[0] == "| generation | 1 | 3 |"  # 50 is past what both sides reached
    ours3, paper3 = np.array([250.0, 330.0]), np.array([300.0, 310.0, 400.0])
    assert lines[2] == f"| Connections-GA, ours (2 seeds) | 100 +- 14 | 290 +- {ours3.std(ddof=1):.0f} |"
    assert lines[3] == f"| Connections-GA, paper (v2, 3 seeds) | 100 +- 20 | 337 +- {paper3.std(ddof=1):.0f} |"
    assert lines[4] == f"| ours / paper | 1.00 | {ours3.mean() / paper3.mean():.2f} |"
    p = welch(ours3.mean(), ours3.std(ddof=1), 2, paper3.mean(), paper3.std(ddof=1), 3).p
    assert lines[5] == f"| Welch's p | 1 | {p:.2g} |"
    assert "First generation at R = 200 (--level), by seed:" in text
    assert "- Connections-GA, ours: 0: 3, 1: 2 (median 2.5)" in text
    assert "- Connections-GA, paper: 10: 2, 20: 2, 30: 3 (median 2)" in text


def test_level_defaults_to_the_papers_r(runs, tmp_path):
    write_reference(tmp_path / "ref")
    text = by_generation([runs], tmp_path / "ref", "swimmer", generations=[1])
    assert "R = 107.52 (the paper's R)" in text
    assert "ours: 0: 2, 1: 1 (median 1.5)" in text


def test_level_is_our_dpn_ppo_runs_r_where_they_finished(runs, tmp_path):
    write_reference(tmp_path / "ref")
    write_run(
        runs, "swimmer", "Swimmer-v5", "dpn_ppo", 0, [150.0, 160.0], kind="ppo", steps_per_row=500, total_env_steps=1000
    )
    text = by_generation([runs], tmp_path / "ref", "swimmer", generations=[1])
    assert "R = 160 (dpn_ppo runs, final return, 1 seed(s))" in text
    assert "ours: 0: 3, 1: 2 (median 2.5)" in text


def test_missing_data_is_one_clear_error(runs, tmp_path, capsys):
    with pytest.raises(SpnError, match="does not exist"):
        by_generation([runs], tmp_path / "nowhere", "swimmer")
    with pytest.raises(SpnError, match="no finished weights_ga runs of env 'swimmer'"):
        by_generation([runs], tmp_path / "ref", "swimmer", algos=["weights_ga"])
    with pytest.raises(SpnError, match="no runs of env 'halfcheetah'"):
        by_generation([runs], tmp_path / "ref", "halfcheetah")
    bad = write_reference(tmp_path / "ref")
    bad.write_text("generation,seed_10\n1,100\n3,200\n")
    with pytest.raises(SystemExit, match="must hold a 'generation' column counting 1, 2, ..."):
        main([str(runs), "--reference", str(tmp_path / "ref"), "--env", "swimmer"])
    bad.write_text("generation,seed_10\n1,oops\n")
    with pytest.raises(SystemExit, match="not a number"):
        main([str(runs), "--reference", str(tmp_path / "ref"), "--env", "swimmer"])


def test_cli_prints_the_table(runs, tmp_path, capsys):
    write_reference(tmp_path / "ref")
    main([str(runs), "--reference", str(tmp_path / "ref"), "--env", "swimmer", "--generations", "2"])
    out = capsys.readouterr().out
    assert out.startswith("| generation | 2 |")
    assert "| Connections-GA, ours (2 seeds) | 180 +- 42 |" in out
