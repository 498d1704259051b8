"""The committed study beyond the paper (beyond/): its report is the command's output over its committed runs."""

import json
import shutil
from pathlib import Path

from spn_torchrl.analysis.collect import MAX_BYTES
from spn_torchrl.analysis.report import build_report

ROOT = Path(__file__).resolve().parents[1]
# beyond/PREFACE.md's command, its shell patterns spelled out as bash expands them
COMMAND = (
    "python -m spn_torchrl.report beyond/runs "
    "reproduction/runs/{halfcheetah,swimmer}__{conn_ga,dpn_ppo}__[0-9] --out beyond/"
)
GA_ARMS = [
    f"reproduction/runs/{env}__{algo}__{seed}"
    for env in ("halfcheetah", "swimmer")
    for algo in ("conn_ga", "dpn_ppo")
    for seed in range(10)
]


def test_the_committed_study_is_what_its_committed_runs_give(tmp_path, monkeypatch):
    """beyond/report.md and report.json are the report over beyond/runs and the reproduction's GA and PPO seeds 0-9,
    never edited by hand; every committed run reached its budget and holds only the three evidence files."""
    committed = ROOT / "beyond"
    assert COMMAND in (committed / "PREFACE.md").read_text()
    for run in (committed / "runs").iterdir():
        assert sorted(p.name for p in run.iterdir()) == ["COMMIT", "config.yaml", "progress.csv"], run
        assert all(p.stat().st_size <= MAX_BYTES for p in run.iterdir()), run
    shutil.copy(committed / "PREFACE.md", tmp_path / "PREFACE.md")
    monkeypatch.chdir(ROOT)  # the report names its paths as given, relative to the checkout
    result = build_report(["beyond/runs", *GA_ARMS], tmp_path)
    assert result["stopped"] == []
    assert (tmp_path / "report.md").read_text() == (committed / "report.md").read_text(), f"run: {COMMAND}"
    assert json.loads((tmp_path / "report.json").read_text()) == json.loads((committed / "report.json").read_text())
    assert sorted(p.name for p in committed.glob("*.png")) == sorted(p.name for p in tmp_path.glob("*.png"))
