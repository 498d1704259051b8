"""Finished (or running) runs on disk: find them, read them, pool their seeds into curves."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from omegaconf import DictConfig, OmegaConf

from spn_torchrl.config import config_dict, from_saved
from spn_torchrl.errors import ConfigError, SpnError
from spn_torchrl.lifecycle import BUDGET, affects_results, flatten
from spn_torchrl.records import read_progress

# where a run's resolved config lies: a Hydra run directory, or a collected copy (reproduction/runs/)
CONFIG_PATHS = (Path(".hydra") / "config.yaml", Path("config.yaml"))
GENERATIONAL = frozenset({"ga", "ec"})  # the kinds that log one row a generation and evolve the SPN's masks or weights


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

    @property
    def budget(self) -> int | None:
        """What the run was asked for: generations (GA) or env steps (PPO); None where the config does not say."""
        value = self.config.algo.get("total_env_steps" if self.kind == "ppo" else "generations")
        return None if value is None else int(value)

    @property
    def done(self) -> int:
        """How far it got: generations logged (GA) or its last total_env_steps (PPO)."""
        if self.kind in GENERATIONAL:
            return len(self.rows)
        return int(self.rows[-1].get("total_env_steps") or 0)

    @property
    def finished(self) -> bool:
        """Whether the run reached its budget (a run whose config states none counts as finished)."""
        return self.budget is None or self.done >= self.budget

    @property
    def progress_text(self) -> str:
        """``3 of 30 generations`` or ``2000 of 1000000 env steps``."""
        unit = "env steps" if self.kind == "ppo" else "generations"
        return f"{self.done} of {'?' if self.budget is None else self.budget} {unit}"

    @property
    def results_config(self) -> dict[str, str]:
        """The fields of its config that change results (as the resume contract counts them), less the seed (what
        is pooled), the budget (runs of different lengths are cut to the rows all reached) and ``env.name`` (a
        label): two runs that differ here are not seeds of one method. The config is read as today's schema
        (:func:`config.from_saved`: moved fields in their new place, fields added since at their defaults), so a
        run saved before a field existed pools with the runs that state its default."""
        saved = OmegaConf.to_container(self.config, resolve=False)
        try:
            saved = config_dict(from_saved(saved))
        except ConfigError:  # a config today's schema cannot read: compared as saved
            pass
        flat = flatten(saved)
        skip = ("seed", "env.name", BUDGET.get(self.kind, ""))
        return {k: repr(v) for k, v in sorted(flat.items()) if k not in skip and affects_results(k, self.kind)}

    def snn(self, name: str, default: Any) -> Any:
        """An SNN constant (``hidden``, ``time_steps``, ...) from ``algo.snn`` (new schema) or ``algo`` (old)."""
        algo = self.config.algo
        snn = algo.get("snn")
        if snn is not None and name in snn:
            return snn[name]
        return algo.get(name, default)

    def column(self, name: str) -> np.ndarray:
        """One progress.csv column as floats (NaN where a row lacks it)."""
        return np.array([float(row.get(name, np.nan)) if row.get(name, "") != "" else np.nan for row in self.rows])


def config_path(run_dir: str | Path) -> Path | None:
    """A run directory's resolved config: ``.hydra/config.yaml`` (Hydra) or ``config.yaml`` (a collected copy)."""
    for relative in CONFIG_PATHS:
        if (Path(run_dir) / relative).is_file():
            return Path(run_dir) / relative
    return None


def find_runs(paths: Iterable[str | Path]) -> list[RunRecord]:
    """Every directory under ``paths`` (or a path itself) holding progress.csv and its config (``.hydra/config.yaml``
    or ``config.yaml``) with at least one row; :class:`SpnError` for a path that does not exist."""
    found: dict[Path, RunRecord] = {}
    for root in map(Path, paths):
        if not root.exists():
            raise SpnError(f"{root} does not exist")
        candidates = [root / "progress.csv"] if (root / "progress.csv").exists() else []
        candidates += sorted(root.rglob("progress.csv")) if root.is_dir() else []
        for progress in candidates:
            run_dir = progress.parent.resolve()
            config = config_path(run_dir)
            if run_dir in found or config is None:
                continue
            rows = read_progress(progress)
            if rows:
                found[run_dir] = RunRecord(run_dir, OmegaConf.load(config), rows)
    return sorted(found.values(), key=lambda r: (r.env, r.algo, r.seed, str(r.path)))


def split_finished(runs: Sequence[RunRecord]) -> tuple[list[RunRecord], list[RunRecord]]:
    """(runs that reached their budget, runs that stopped early or are still running)."""
    return [r for r in runs if r.finished], [r for r in runs if not r.finished]


def pool_choice(runs: Sequence[RunRecord]) -> tuple[list[RunRecord], list[RunRecord]]:
    """(runs to pool, runs left out) of one method on one task: the finished runs, the others left out; where
    none finished, every run is pooled (the caller says so) over the rows they all reached."""
    finished, stopped = split_finished(runs)
    return (finished, stopped) if finished else (list(runs), [])


def group_runs(runs: Sequence[RunRecord]) -> dict[str, dict[str, list[RunRecord]]]:
    """``{task: {method: [runs, seeds pooled]}}``. The task is ``env.id``, named by its ``env.name`` (or
    ``{env.name}__{env.id}`` where one name labels several ids); a method is ``algo.name`` and the config fields that
    change results (:meth:`RunRecord.results_config`): where the runs of one name differ there, each config is its own
    method, named ``algo (field=value, ...)`` by the fields that differ."""
    names: dict[str, set[str]] = {}
    for run in runs:
        names.setdefault(run.env, set()).add(run.env_id)
    by_task: dict[str, dict[str, list[RunRecord]]] = {}
    for run in runs:
        task = run.env if len(names[run.env]) == 1 else f"{run.env}__{run.env_id}"
        by_task.setdefault(task, {}).setdefault(run.algo, []).append(run)
    return {task: _split_configs(algos) for task, algos in by_task.items()}


def _split_configs(algos: dict[str, list[RunRecord]]) -> dict[str, list[RunRecord]]:
    out: dict[str, list[RunRecord]] = {}
    for algo, runs in algos.items():
        configs: list[dict[str, str]] = []
        for run in runs:
            if run.results_config not in configs:
                configs.append(run.results_config)
        if len(configs) == 1:
            out[algo] = runs
            continue
        differ = sorted({k for c in configs for k in {*c, *configs[0]} if c.get(k) != configs[0].get(k)})
        for config in configs:
            label = ", ".join(f"{k}={config.get(k, '<absent>')}" for k in differ)
            out[f"{algo} ({label})"] = [run for run in runs if run.results_config == config]
    return out


def split_duplicates(runs: Sequence[RunRecord]) -> tuple[list[RunRecord], list[RunRecord]]:
    """(one run per seed, the others): a seed repeated under one method (the same run copied, or run twice) counts
    once, its first run by path; the repeats are listed apart, never pooled as further seeds."""
    seen: set[int] = set()
    unique, repeats = [], []
    for run in sorted(runs, key=lambda r: str(r.path)):
        (repeats if run.seed in seen else unique).append(run)
        seen.add(run.seed)
    return sorted(unique, key=lambda r: (r.seed, str(r.path))), repeats


def common_length(runs: Sequence[RunRecord]) -> int:
    """The rows (generations or iterations) that every run of ``runs`` reached."""
    return min(len(run.rows) for run in runs)


def longer_groups(runs: Sequence[RunRecord]) -> list[list[RunRecord]]:
    """The runs of ``runs`` that went past the rows every run reached, grouped by their length (shortest first)."""
    common = common_length(runs)
    lengths = sorted({len(run.rows) for run in runs} - {common})
    return [[run for run in runs if len(run.rows) == length] for length in lengths]


def pooled(runs: Sequence[RunRecord], name: str) -> np.ndarray:
    """Column ``name`` of every run stacked as [seeds, rows], cut to the rows every run reached."""
    length = common_length(runs)
    return np.stack([run.column(name)[:length] for run in runs])


def mean_std(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and (population) std over seeds, axis 0."""
    return values.mean(axis=0), values.std(axis=0)


def last_value(runs: Sequence[RunRecord], name: str) -> float:
    """Mean over seeds of ``name`` at the last row every run reached (NaN if no run logged it)."""
    row = common_length(runs) - 1
    values = [run.column(name)[row] for run in runs if name in run.rows[row]]
    return float(np.mean(values)) if values else float("nan")
