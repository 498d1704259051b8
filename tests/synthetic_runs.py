"""FIXTURES, not real runs: run directories written by hand (config + progress.csv) for fast report tests."""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from spn_torchrl.analysis.runs import GENERATIONAL

GA_FIELDS = [
    "generation",
    "eval_return",
    "total_env_steps",
    "mask_density",
    "spike_rate",
    "synapses_l1",
    "synapses_l2",
]


def write_run(
    root: Path,
    env: str,
    env_id: str,
    algo: str,
    seed: int,
    returns: Sequence[float],
    generations: int | None = None,
    layout: str = "hydra",
    kind: str = "ga",
    steps_per_row: int = 1000,
    total_env_steps: int | None = None,
    snn_schema: str = "old",
    backend: str | None = None,
) -> Path:
    """A run directory ``root/{env}__{algo}__{seed}`` whose rows hold ``returns``; ``generations`` is the budget
    (default: as many as rows), ``layout`` "hydra" (.hydra/config.yaml) or "flat" (config.yaml), ``backend`` the
    env.backend stated (none by default)."""
    run = root / f"{env}__{algo}__{seed}"
    run.mkdir(parents=True)
    generations = len(returns) if generations is None else generations
    snn = "  hidden: 64\n  time_steps: 4\n" if snn_schema == "old" else "  snn:\n    hidden: 64\n    time_steps: 4\n"
    generational = kind in GENERATIONAL
    budget = f"  generations: {generations}\n" if generational else f"  total_env_steps: {total_env_steps}\n"
    config = (
        f"algo:\n  name: {algo}\n  kind: {kind}\n{budget}  population: 200\n  elite_candidates: 10\n"
        f"  elite_episodes: 10\n{snn}env:\n  name: {env}\n  id: {env_id}\n"
        + (f"  backend: {backend}\n" if backend else "")
        + f"seed: {seed}\n"
    )
    (run / ".hydra" if layout == "hydra" else run).mkdir(exist_ok=True)
    (run / (".hydra/config.yaml" if layout == "hydra" else "config.yaml")).write_text(config)
    with open(run / "progress.csv", "w", newline="") as f:
        writer = csv.writer(f)
        if generational:
            writer.writerow(GA_FIELDS)
            for g, value in enumerate(returns, start=1):
                writer.writerow([g, value, g * steps_per_row, 0.5, 0.1, 500, 200])
        else:
            writer.writerow(["iteration", "total_env_steps", "eval_return"])
            for i, value in enumerate(returns, start=1):
                writer.writerow([i, i * steps_per_row, value])
    return run
