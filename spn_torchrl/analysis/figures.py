"""Learning-curve figures of the report (matplotlib, Agg backend): mean and half-std band over seeds."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.ticker import NullFormatter  # noqa: E402

from spn_torchrl.analysis.runs import GENERATIONAL, RunRecord, longer_groups, mean_std, pooled  # noqa: E402

COLORS = {"conn_ga": "tab:purple", "weights_ga": "tab:blue", "dpn_ppo": "tab:red", "conn_ppo": "tab:green"}


def _band(ax, x, runs: Sequence[RunRecord], label: str, color: str | None) -> None:
    mean, std = mean_std(pooled(runs, "eval_return"))
    # PPO evaluates every eval_interval iterations and logs NaN between: plot the evaluated points only.
    evaluated = np.isfinite(mean)
    x, mean, std = np.asarray(x)[evaluated], mean[evaluated], std[evaluated]
    line = ax.plot(x, mean, label=f"{label} ({len(runs)} seed(s))", color=color)[0]
    ax.fill_between(x, mean - std / 2, mean + std / 2, alpha=0.25, color=line.get_color(), linewidth=0)


def _longer(ax, x_name: str, runs: Sequence[RunRecord], label: str, color: str | None) -> None:
    """The runs that went past the pooled rows, over their whole length: a dashed mean line per length."""
    for group in longer_groups(runs):
        x = pooled(group, x_name).mean(axis=0)
        seeds = ", ".join(str(run.seed) for run in group)
        ax.plot(
            x,
            pooled(group, "eval_return").mean(axis=0),
            color=color,
            linestyle="--",
            linewidth=1,
            label=f"{label}: seed(s) {seeds} on to {len(group[0].rows)}",
        )


def task_figure(
    title: str,
    algos: dict[str, list[RunRecord]],
    ppo_level: float | None,
    path: Path,
    reached: dict[str, int | None] | None = None,
    published: dict[str, tuple[int, float, float]] | None = None,
    level_note: str = "",
) -> Path:
    """Return vs generation (GA and EC runs) and vs env steps (every method, one shared log axis) for one task.

    ``reached`` maps a GA or EC method to G, the generation its mean curve reaches the PPO level (a dotted line);
    ``published`` maps a GA method to a published (generation, mean, std): a marker with a half-std bar.
    ``level_note`` follows the PPO level in the legend (e.g. "paper's R").
    """
    fig, (by_gen, by_steps) = plt.subplots(1, 2, figsize=(11, 4))
    for algo, runs in sorted(algos.items()):
        color = COLORS.get(algo)
        steps = pooled(runs, "total_env_steps").mean(axis=0)
        if runs[0].kind in GENERATIONAL:
            _band(by_gen, pooled(runs, "generation")[0], runs, algo, color)
            _longer(by_gen, "generation", runs, algo, color)
            _longer(by_steps, "total_env_steps", runs, algo, color)
            generation = (reached or {}).get(algo)
            if generation is not None:
                by_gen.axvline(
                    generation, color=color, linestyle=":", linewidth=1, label=f"{algo} reaches R: G={generation}"
                )
                by_steps.axvline(steps[generation - 1], color=color, linestyle=":", linewidth=1)
        _band(by_steps, steps, runs, algo, color)
        if runs[0].kind in GENERATIONAL and algo in (published or {}):
            generation, mean, std = published[algo]
            by_gen.errorbar(
                generation,
                mean,
                yerr=std / 2,
                fmt="D",
                color=color,
                capsize=3,
                label=f"{algo}: paper, gen {generation}",
            )
    for ax in (by_gen, by_steps):
        if ppo_level is not None:
            ax.axhline(
                ppo_level,
                color="red",
                linestyle="--",
                linewidth=1,
                label=f"PPO level {ppo_level:.6g}{f' ({level_note})' if level_note else ''}",
            )
        ax.set_ylabel("return (elite, mean of eval episodes)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    by_gen.set_xlabel("generation")
    by_steps.set_xlabel("env steps (log scale)")
    by_steps.set_xscale("log")
    by_steps.xaxis.set_minor_formatter(NullFormatter())  # labelled minor ticks overlap on a short range
    kinds = sorted({runs[0].kind.upper() for runs in algos.values() if runs[0].kind in GENERATIONAL})
    by_gen.set_title(f"{title}: return vs generation" + (f" ({', '.join(kinds)})" if kinds else ""))
    by_steps.set_title(f"{title}: return vs env steps")
    caption = "line: mean over seeds; band: +- half a std over seeds"
    if any(longer_groups(runs) for runs in algos.values() if runs[0].kind in GENERATIONAL):
        caption += "; dashed: the runs that went on past the rest"
    fig.text(0.5, 0.005, caption, ha="center", fontsize=8)
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
