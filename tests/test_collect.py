"""Collecting finished runs into reproduction/runs: what is copied, what is refused."""

import subprocess
import sys
from pathlib import Path

import pytest
from omegaconf import OmegaConf
from synthetic_runs import write_run

from spn_torchrl.analysis.collect import MAX_BYTES, CollectError, collect_run
from spn_torchrl.analysis.runs import find_runs

ROOT = Path(__file__).resolve().parents[1]
COMMIT = "d00a600beff4d6a79edfac074be7c08d9c2ce4be"


def finished(root: Path, seed: int = 0) -> Path:
    return write_run(root / "runs", "cartpole", "CartPole-v1", "conn_ga", seed, [1.0, 2.0, 3.0])


def test_a_finished_run_is_copied_with_its_config_and_commit(tmp_path):
    run = finished(tmp_path)
    into = tmp_path / "reproduction" / "runs"
    assert "collected" in collect_run(run, into, COMMIT)
    target = into / "cartpole__conn_ga__0"
    assert sorted(p.name for p in target.iterdir()) == ["COMMIT", "config.yaml", "progress.csv"]
    assert (target / "progress.csv").read_bytes() == (run / "progress.csv").read_bytes()
    assert (target / "COMMIT").read_text() == COMMIT + "\n"
    assert OmegaConf.load(target / "config.yaml") == OmegaConf.load(run / ".hydra" / "config.yaml")
    [collected] = find_runs([into])  # the report reads the collected layout
    assert collected.seed == 0 and collected.finished and len(collected.rows) == 3
    assert "identical" in collect_run(run, into, COMMIT)  # again: nothing changes
    assert "already in place" in collect_run(target, into)  # its own COMMIT file is its commit


def test_the_config_is_written_resolved(tmp_path):
    run = finished(tmp_path)
    config = run / ".hydra" / "config.yaml"
    config.write_text(config.read_text() + "run_name: ${env.name}_run\n")
    collect_run(run, tmp_path / "into", COMMIT)
    assert "run_name: cartpole_run" in (tmp_path / "into" / "cartpole__conn_ga__0" / "config.yaml").read_text()


def test_an_unfinished_run_is_refused(tmp_path):
    run = write_run(tmp_path, "cartpole", "CartPole-v1", "conn_ga", 1, [1.0, 2.0], generations=100)
    with pytest.raises(CollectError, match="did not reach its budget: 2 of 100 generations"):
        collect_run(run, tmp_path / "into", COMMIT)
    assert not (tmp_path / "into").exists()
    ppo = write_run(tmp_path, "cartpole", "CartPole-v1", "dpn_ppo", 0, [1, 2], kind="ppo", total_env_steps=10_000)
    with pytest.raises(CollectError, match="2000 of 10000 env steps"):
        collect_run(ppo, tmp_path / "into", COMMIT)


def test_a_different_existing_file_is_not_overwritten_silently(tmp_path):
    run = finished(tmp_path)
    into = tmp_path / "into"
    collect_run(run, into, COMMIT)
    with pytest.raises(CollectError, match="already holds a different COMMIT: pass --replace"):
        collect_run(run, into, "abcdef1")
    assert (into / "cartpole__conn_ga__0" / "COMMIT").read_text() == COMMIT + "\n"
    assert "replaced COMMIT" in collect_run(run, into, "abcdef1", replace=True)
    assert (into / "cartpole__conn_ga__0" / "COMMIT").read_text() == "abcdef1\n"


def test_refusals_without_commit_bad_commit_or_too_large(tmp_path):
    run = finished(tmp_path)
    with pytest.raises(CollectError, match="records no commit: pass --commit"):
        collect_run(run, tmp_path / "into")
    with pytest.raises(CollectError, match="hex commit hash"):
        collect_run(run, tmp_path / "into", "HEAD")
    long = write_run(tmp_path / "long", "cartpole", "CartPole-v1", "conn_ga", 0, [1.0] * (MAX_BYTES // 25))
    assert (long / "progress.csv").stat().st_size > MAX_BYTES
    with pytest.raises(CollectError, match="progress.csv is .* bytes, over the 1000000-byte limit"):
        collect_run(long, tmp_path / "into", COMMIT)
    assert not (tmp_path / "into").exists()
    with pytest.raises(CollectError, match="not a run directory"):
        collect_run(tmp_path / "nothing", tmp_path / "into", COMMIT)


@pytest.mark.slow  # processes or a CLI in a subprocess
def test_cli_collects_the_finished_and_names_the_refused(tmp_path):
    good = finished(tmp_path)
    bad = write_run(tmp_path / "runs", "cartpole", "CartPole-v1", "conn_ga", 1, [1.0], generations=5)
    cmd = [sys.executable, "-m", "spn_torchrl.analysis.collect", str(good), str(bad), "--into", str(tmp_path / "o")]
    proc = subprocess.run([*cmd, "--commit", COMMIT], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode != 0 and "Traceback" not in proc.stderr
    assert "did not reach its budget: 1 of 5 generations" in proc.stderr
    assert "1 of 2 run(s) refused" in proc.stderr
    assert (tmp_path / "o" / "cartpole__conn_ga__0" / "COMMIT").exists()
    assert not (tmp_path / "o" / "cartpole__conn_ga__1").exists()
