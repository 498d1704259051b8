"""Finished (or running) runs on disk: find them, read them, pool their seeds into curves."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from spn_torchrl.records import read_progress


@dataclass
class RunRecord:
    """One run directory: its resolved Hydra config and its progress.csv rows."""

    path: Path
    config: DictConfig
    rows: list[dict[str, Any]]

    @property
    def algo(self) -> str:
        return str(self.config.algo.name)

    @property
    def kind(self) -> str:
        return str(self.config.algo.get("kind", "ga"))

    @property
    def env(self) -> str:
        return str(self.config.env.name)

    @property
    def env_id(self) -> str:
        return str(self.config.env.id)

    @property
    def seed(self) -> int:
        return int(self.config.seed)

    def column(self, name: str) -> np.ndarray:
        """One progress.csv column as floats (NaN where a row lacks it)."""
        return np.array([float(row.get(name, np.nan)) if row.get(name, "") != "" else np.nan for row in self.rows])


def find_runs(paths: Iterable[str | Path]) -> list[RunRecord]:
    """Every directory under ``paths`` (or a path itself) holding progress.csv and .hydra/config.yaml."""
    found: dict[Path, RunRecord] = {}
    for root in map(Path, paths):
        candidates = [root / "progress.csv"] if (root / "progress.csv").exists() else []
        candidates += sorted(root.rglob("progress.csv")) if root.is_dir() else []
        for progress in candidates:
            run_dir = progress.parent.resolve()
            config = run_dir / ".hydra" / "config.yaml"
            if run_dir in found or not config.exists():
                continue
            rows = read_progress(progress)
            if rows:
                found[run_dir] = RunRecord(run_dir, OmegaConf.load(config), rows)
    return sorted(found.values(), key=lambda r: (r.env, r.algo, r.seed, str(r.path)))


def group_runs(runs: Sequence[RunRecord]) -> dict[str, dict[str, list[RunRecord]]]:
    """``{env: {algo: [runs, seeds pooled]}}``."""
    groups: dict[str, dict[str, list[RunRecord]]] = {}
    for run in runs:
        groups.setdefault(run.env, {}).setdefault(run.algo, []).append(run)
    return groups


def pooled(runs: Sequence[RunRecord], name: str) -> np.ndarray:
    """Column ``name`` of every run stacked as [seeds, rows], cut to the shortest run."""
    length = min(len(run.rows) for run in runs)
    return np.stack([run.column(name)[:length] for run in runs])


def mean_std(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and (population) std over seeds, axis 0."""
    return values.mean(axis=0), values.std(axis=0)


def last_value(runs: Sequence[RunRecord], name: str) -> float:
    """Mean over seeds of each run's last value of ``name`` (NaN if no run logged it)."""
    values = [run.column(name)[-1] for run in runs if name in run.rows[-1]]
    return float(np.mean(values)) if values else float("nan")
