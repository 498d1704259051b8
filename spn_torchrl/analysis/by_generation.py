"""Our seeds against the authors' per-seed logs, generation by generation: the reproduction preface's tables.

``python -m spn_torchrl.analysis.by_generation reproduction/runs --reference DIR --env humanoidstandup
[--algo ...] [--generations 1 5 10 20] [--level R]`` reads the finished runs of a task under the
given paths and the authors' ``<Env>_SPN_<Variant>_elite_returns_by_gen.csv`` in ``DIR`` (the logged elite return
of each of their seeds, one row per generation), and prints a markdown table: per method and generation, our mean
+- sample std over seeds, theirs, the ratio and Welch's two-sided p; then each seed's first generation at the PPO
level R (``--level``, else our finished dpn_ppo runs' R, else the paper's). The reference files stay outside the
repository; the numbers this prints may be quoted.
"""

from __future__ import annotations

import argparse
import csv
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from spn_torchrl.analysis import paper
from spn_torchrl.analysis.energy import first_generation_at
from spn_torchrl.analysis.report import PPO_LEVEL_ALGO, ppo_level
from spn_torchrl.analysis.runs import find_runs, group_runs, pool_choice, pooled
from spn_torchrl.analysis.stats import welch
from spn_torchrl.errors import SpnError

# the paper's task ids and the variant names of the reference files, keyed by the project's env.name / algo.name
PAPER_ENV_IDS = {
    "cartpole": "CartPole-v1",
    "halfcheetah": "HalfCheetah-v2",
    "swimmer": "Swimmer-v2",
    "humanoidstandup": "HumanoidStandup-v2",
}
VARIANTS = {"conn_ga": "Connections", "weights_ga": "Weights"}
DEFAULT_GENERATIONS = (1, 2, 5, 10, 20, 50, 100)


@dataclass
class Curves:
    """Eval returns per seed, [seeds, generations] (generation 1 first), with each row's seed."""

    returns: np.ndarray
    seeds: list[int]


def reference_path(reference: str | Path, env: str, algo: str) -> Path:
    """The authors' per-seed log of a task and GA method in the reference directory."""
    if env not in PAPER_ENV_IDS or algo not in VARIANTS:
        raise SpnError(f"no published per-seed log for env {env!r} and algo {algo!r}")
    return Path(reference) / f"{PAPER_ENV_IDS[env]}_SPN_{VARIANTS[algo]}_elite_returns_by_gen.csv"


def read_reference(path: str | Path) -> Curves:
    """The authors' log: columns ``generation`` and ``seed_S`` (one per published seed); other columns ignored."""
    path = Path(path)
    if not path.is_file():
        raise SpnError(f"published per-seed log {path} does not exist")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    columns = [c for c in (rows[0] if rows else {}) if c.startswith("seed_")]
    if not columns or any(row.get("generation") != str(g) for g, row in enumerate(rows, start=1)):
        raise SpnError(f"{path} must hold a 'generation' column counting 1, 2, ... and one 'seed_S' column per seed")
    try:
        returns = np.array([[float(row[c]) for row in rows] for c in columns])
    except (TypeError, ValueError) as err:
        raise SpnError(f"{path}: a seed column holds a value that is not a number ({err})") from None
    return Curves(returns, [int(c.removeprefix("seed_")) for c in columns])


def our_curves(paths: Sequence[str | Path], env: str) -> tuple[dict[str, Curves], float, str]:
    """Our finished GA runs of ``env`` by algo (``eval_return`` per seed) and the PPO level R with its source."""
    algos = group_runs(find_runs(paths)).get(env)
    if not algos:
        raise SpnError(f"no runs of env {env!r} under {', '.join(map(str, paths))}")
    curves = {}
    for algo, runs in algos.items():
        if algo in VARIANTS:
            pool, _ = pool_choice(runs)
            curves[algo] = Curves(pooled(pool, "eval_return"), [run.seed for run in pool])
    ppo = {PPO_LEVEL_ALGO: pool_choice(algos[PPO_LEVEL_ALGO])[0]} if PPO_LEVEL_ALGO in algos else {}
    level, source = ppo_level(ppo, None)
    if level is None:
        level = paper.CARTPOLE_LIMIT if env == "cartpole" else paper.PPO_LEVEL[env]
        source = "the return limit" if env == "cartpole" else "the paper's R"
    return curves, level, source


def _value(x: float, scale: float) -> str:
    return f"{x:.0f}" if abs(scale) >= 100 else f"{x:.1f}"


def _p(p: float) -> str:
    return "< 0.001" if p < 0.001 else f"{p:.2g}"


def generation_rows(
    title: str, ours: Curves, theirs: Curves, generations: Sequence[int], version: str
) -> list[list[str]]:
    """Four table rows of one method: ours, the paper's (on task ``version``), ours / paper, Welch's p (blank where
    a side has fewer than 2 seeds)."""
    rows: list[list[str]] = [
        [f"{title}, ours ({len(ours.seeds)} seeds)"],
        [f"{title}, paper ({version}, {len(theirs.seeds)} seeds)"],
        ["ours / paper"],
        ["Welch's p"],
    ]
    for g in generations:
        a, b = ours.returns[:, g - 1], theirs.returns[:, g - 1]
        sd_a = float(a.std(ddof=1)) if len(a) > 1 else float("nan")
        sd_b = float(b.std(ddof=1)) if len(b) > 1 else float("nan")
        rows[0].append(f"{_value(a.mean(), a.mean())} +- {_value(sd_a, a.mean())}")
        rows[1].append(f"{_value(b.mean(), b.mean())} +- {_value(sd_b, b.mean())}")
        rows[2].append(f"{a.mean() / b.mean():.2f}" if b.mean() else "")
        rows[3].append(_p(welch(a.mean(), sd_a, len(a), b.mean(), sd_b, len(b)).p) if min(len(a), len(b)) > 1 else "")
    return rows


def first_at(curves: Curves, level: float) -> str:
    """Each seed's first generation at ``level`` (``never`` if none), with the median over seeds that reached it."""
    firsts = [first_generation_at(row.tolist(), level) for row in curves.returns]
    text = ", ".join(f"{s}: {'never' if g is None else g}" for s, g in zip(curves.seeds, firsts, strict=True))
    reached = [g for g in firsts if g is not None]
    return text + (f" (median {float(np.median(reached)):g})" if reached else "")


def by_generation(
    paths: Sequence[str | Path],
    reference: str | Path,
    env: str,
    algos: Sequence[str] | None = None,
    generations: Sequence[int] = DEFAULT_GENERATIONS,
    level: float | None = None,
) -> str:
    """The markdown table and the first-generation-at-R lines of ``env`` for ``algos`` (default: every GA method
    with finished runs); :class:`SpnError` for missing data."""
    curves, our_level, source = our_curves(paths, env)
    algos = [algo for algo in VARIANTS if algo in curves] if algos is None else algos
    if level is not None:
        our_level, source = level, "--level"
    pairs = []
    for algo in algos:
        if algo not in curves:
            raise SpnError(f"no finished {algo} runs of env {env!r} under {', '.join(map(str, paths))}")
        pairs.append((algo, curves[algo], read_reference(reference_path(reference, env, algo))))
    reach = min(min(ours.returns.shape[1], theirs.returns.shape[1]) for _, ours, theirs in pairs)
    shown = [g for g in generations if 1 <= g <= reach]
    if not shown:
        raise SpnError(f"none of generations {list(generations)} is in 1..{reach}, the generations both sides reached")
    table = [["generation", *map(str, shown)], ["---"] * (len(shown) + 1)]
    for algo, ours, theirs in pairs:
        table += generation_rows(paper.METHOD_TITLES[algo], ours, theirs, shown, PAPER_ENV_IDS[env].split("-")[-1])
    lines = ["| " + " | ".join(row) + " |" for row in table]
    lines += ["", "std: sample std over seeds; p: Welch's two-sided t-test of our seeds against the paper's.", ""]
    lines.append(f"First generation at R = {our_level:.6g} ({source}), by seed:")
    for algo, ours, theirs in pairs:
        title = paper.METHOD_TITLES[algo]
        lines += [f"- {title}, ours: {first_at(ours, our_level)}", f"- {title}, paper: {first_at(theirs, our_level)}"]
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(
        prog="python -m spn_torchrl.analysis.by_generation", description=__doc__.splitlines()[0]
    )
    parser.add_argument("runs", nargs="+", type=Path, help="run directories or folders of them (reproduction/runs)")
    parser.add_argument("--reference", required=True, type=Path, help="folder of the authors' per-seed logs")
    parser.add_argument("--env", required=True, choices=sorted(PAPER_ENV_IDS), help="the task (env.name)")
    parser.add_argument("--algo", nargs="+", choices=sorted(VARIANTS), help="default: those with runs")
    parser.add_argument("--generations", nargs="+", type=int, default=list(DEFAULT_GENERATIONS))
    parser.add_argument("--level", type=float, default=None, help="the PPO level R (default: ours, else the paper's)")
    args = parser.parse_args(argv)
    try:
        print(by_generation(args.runs, args.reference, args.env, args.algo, args.generations, args.level))
    except SpnError as err:
        sys.exit(f"error: {err}")


if __name__ == "__main__":
    main()
