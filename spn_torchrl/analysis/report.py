"""One report over run / multirun directories: curves over seeds, data efficiency, energy (paper Tables 1-4).

``python -m spn_torchrl.report PATH... [--ppo-level R] [--out DIR] [--wandb]`` writes ``report.md``,
``report.json`` (the same numbers, for tools) and one PNG per task into ``--out``; a ``PREFACE.md`` already in
``--out`` goes verbatim at the top of ``report.md``.

Runs that did not reach their budget are listed apart, never pooled with finished ones; a method none of whose
runs finished is pooled over the generations every run reached, and says so.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any

from spn_torchrl.analysis import energy
from spn_torchrl.analysis.energy import sig
from spn_torchrl.analysis.figures import task_figure
from spn_torchrl.analysis.runs import (
    GENERATIONAL,
    RunRecord,
    common_length,
    find_runs,
    group_runs,
    last_value,
    longer_groups,
    pool_choice,
    pooled,
    split_duplicates,
    split_finished,
)
from spn_torchrl.analysis.stats import TTest, p_text, welch
from spn_torchrl.envs import task_spec
from spn_torchrl.errors import SpnError

PPO_LEVEL_ALGO = "dpn_ppo"
PAPER_BUDGET = {
    "generations": 100,
    "population": 200,
    "elite_candidates": 10,
    "elite_episodes": 10,
    "total_env_steps": 1_000_000,
}


def _nan_to_none(value: float) -> float | None:
    return None if value is None or math.isnan(value) else float(value)


def shown_path(path: Path) -> str:
    """A run's path as the report prints it: relative to the working directory when under it (so that a report
    written from committed evidence does not depend on where the repository lies), else absolute."""
    try:
        return str(path.relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


def left_out_entry(run: RunRecord) -> dict[str, Any]:
    """A run left out of a pooled curve: seed, how far it got of its budget, where it is."""
    return {
        "seed": run.seed,
        "progress": run.progress_text,
        "done": run.done,
        "budget": run.budget,
        "path": shown_path(run.path),
    }


def method_summary(runs: Sequence[RunRecord], left_out: Sequence[RunRecord] = ()) -> dict[str, Any]:
    """Seeds, length, env steps and final return (mean, std and range over seeds) of one method on one task.

    ``runs`` are the pooled runs (cut to the rows they all reached), ``left_out`` the runs listed apart; ``longer``
    summarises, the same way, the runs that went past that row (grouped by length), and ``budget`` is the shortest
    run's.
    """
    final = pooled(runs, "eval_return")[:, -1]
    algo = min(runs, key=lambda run: len(run.rows)).config.algo
    keys = ("generations", "population", "elite_candidates", "elite_episodes", "total_env_steps")
    return {
        "kind": runs[0].kind,
        "budget": {k: algo[k] for k in keys if k in algo and (k == "total_env_steps") == (runs[0].kind == "ppo")},
        "seeds": sorted(run.seed for run in runs),
        "rows": common_length(runs),
        "rows_per_run": sorted({len(run.rows) for run in runs}),
        "finished": all(run.finished for run in runs),
        "unfinished_pooled": [left_out_entry(run) for run in runs if not run.finished],
        "left_out": [left_out_entry(run) for run in left_out],
        "total_env_steps": last_value(runs, "total_env_steps"),
        "final_return_mean": float(final.mean()),
        "final_return_std": float(final.std()),
        "final_return_sd": float(final.std(ddof=1)) if len(final) > 1 else None,
        "final_return_min": float(final.min()),
        "final_return_max": float(final.max()),
        "return_mean_curve": [float(v) for v in pooled(runs, "eval_return").mean(axis=0)],
        "runs": [shown_path(run.path) for run in runs],
        "longer": [method_summary(group) for group in longer_groups(runs)],
    }


def ppo_level(
    algos: dict[str, list[RunRecord]], override: float | None, source: str = "--ppo-level"
) -> tuple[float | None, str]:
    """The PPO level R: ``override`` if given (from ``source``), else the DPN-PPO runs' final return (mean over seeds)."""
    if override is not None:
        return override, source
    runs = algos.get(PPO_LEVEL_ALGO)
    if runs:
        return float(
            pooled(runs, "eval_return")[:, -1].mean()
        ), f"{PPO_LEVEL_ALGO} runs, final return, {len(runs)} seed(s)"
    return None, "no PPO run found and no --ppo-level given"


def data_efficiency(runs: Sequence[RunRecord], level: float, ppo_steps: float) -> dict[str, Any]:
    """G on the mean-over-seeds curve, E = env steps used up to G (measured, mean over seeds), gamma = E / PPO steps."""
    returns = pooled(runs, "eval_return")
    generation = energy.first_generation_at(returns.mean(axis=0).tolist(), level)
    per_seed = [energy.first_generation_at(r.tolist(), level) for r in returns]
    out: dict[str, Any] = {"G": generation, "seeds_reaching": sum(g is not None for g in per_seed), "seeds": len(runs)}
    out["per_seed_G"] = per_seed
    if generation is None:
        out.update(E=None, gamma=None, A=None)
        return out
    used = float(pooled(runs, "total_env_steps")[:, generation - 1].mean())
    out.update(E=used, gamma=used / ppo_steps, A=used / generation)
    return out


def inference_energy(runs: Sequence[RunRecord], n: int, m: int) -> dict[str, Any]:
    """E_SPN of the final elites (mean over seeds), dense and mask-aware, beside E_DPN (pJ per env step)."""
    hidden, time_steps = int(runs[0].snn("hidden", energy.HIDDEN)), int(runs[0].snn("time_steps", 4))
    rate = last_value(runs, "spike_rate")
    syn1, syn2 = last_value(runs, "synapses_l1"), last_value(runs, "synapses_l2")
    e_dpn = energy.e_dpn(n, m, hidden)
    spn = energy.inference_energy(n, m, hidden, rate, syn1, syn2)  # NaN mask-aware where no synapse counts
    dense, masked = spn["dense_pj"], spn["mask_aware_pj"]
    return {
        "hidden": hidden,
        "rate_per_sim_step": rate,
        "rate_per_env_step": energy.rate_per_env_step(rate, time_steps),
        "mask_density": last_value(runs, "mask_density"),
        "synapses_l1": _nan_to_none(syn1),
        "synapses_l2": _nan_to_none(syn2),
        "e_dpn": e_dpn,
        "e_spn_dense": dense,
        "e_spn_mask": _nan_to_none(masked),
        "ratio_dense": e_dpn / dense,
        "ratio_mask": _nan_to_none(e_dpn / masked),
    }


def ppo_energy(algos: dict[str, list[RunRecord]], n: int, m: int) -> dict[str, Any]:
    """E_PPO of the DPN-PPO runs from their counted passes, else the paper's counts (2.6e7 / 2.5e7), labelled."""
    runs = algos.get(PPO_LEVEL_ALGO)
    if runs and "policy_forward" in runs[0].rows[-1]:
        counts = {
            k: last_value(runs, k) for k in ("policy_forward", "policy_backward", "value_forward", "value_backward")
        }
        return {
            "e_ppo": energy.e_optim_ppo(n, m, **counts),
            "source": f"counted passes of {len(runs)} {PPO_LEVEL_ALGO} run(s), mean over seeds",
            "counts": counts,
            "env_steps": last_value(runs, "total_env_steps"),
        }
    fwd, bwd = energy.ppo_passes()
    return {
        "e_ppo": energy.e_optim_ppo(n, m, fwd, bwd),
        "source": "not measured (no PPO run found): the paper's counts for 1e6 steps, 2.6e7 forward / 2.5e7 backward",
        "counts": {"policy_forward": fwd, "policy_backward": bwd, "value_forward": fwd, "value_backward": bwd},
        "env_steps": energy.PPO_STEPS,
    }


def optim_energy(
    runs: Sequence[RunRecord], infer: dict[str, Any], eff: dict[str, Any] | None, e_ppo: float
) -> dict[str, Any]:
    """E_GA = E_SPN * env steps (to reach R when it was reached, else the whole run), dense and mask-aware."""
    if eff and eff.get("E") is not None:
        steps, source = eff["E"], f"env steps to reach R (generation {eff['G']})"
    else:
        steps = last_value(runs, "total_env_steps")
        source = "whole run: R not reached" if eff else "whole run: no PPO level"
    dense = energy.e_optim_ga(infer["e_spn_dense"], steps)
    masked = energy.e_optim_ga(infer["e_spn_mask"], steps) if infer["e_spn_mask"] is not None else None
    return {
        "env_steps": steps,
        "steps_source": source,
        "e_ga_dense": dense,
        "e_ga_mask": masked,
        "ratio_dense": e_ppo / dense,
        "ratio_mask": e_ppo / masked if masked else None,
    }


def choose_pools(
    algos: dict[str, list[RunRecord]], strict: bool = False
) -> tuple[dict[str, list[RunRecord]], dict[str, list[RunRecord]]]:
    """``({algo: runs to pool}, {algo: runs left out})``: the finished runs are pooled; where none of a method's runs
    finished, ``strict`` leaves the method out altogether, else every run of it is pooled (and marked so)."""
    pools: dict[str, list[RunRecord]] = {}
    left: dict[str, list[RunRecord]] = {}
    for algo, runs in sorted(algos.items()):
        chosen, rest = split_finished(runs) if strict else pool_choice(runs)
        if chosen:
            pools[algo] = chosen
        if rest:
            left[algo] = rest
    return pools, left


def task_summary(
    env: str,
    algos: dict[str, list[RunRecord]],
    level_override: float | None,
    level_source: str = "--ppo-level",
    left_out: dict[str, list[RunRecord]] | None = None,
) -> dict[str, Any]:
    """Every number the report shows for one task, from the pooled runs ``algos`` (``left_out``: listed apart)."""
    left_out = left_out or {}
    any_run = next(iter([*algos.values(), *left_out.values()]))[0]
    spec = task_spec(any_run.env_id)
    n, m = spec.n_obs, spec.n_act
    level, level_source = ppo_level(algos, level_override, level_source)
    ppo = ppo_energy(algos, n, m)
    summary: dict[str, Any] = {
        "env": env,
        "env_id": spec.env_id,
        "n": n,
        "m": m,
        "ppo_level": level,
        "ppo_level_source": level_source,
        "ppo": ppo,
        "methods": {algo: method_summary(runs, left_out.get(algo, ())) for algo, runs in sorted(algos.items())},
        "left_out": {
            algo: [left_out_entry(run) for run in runs] for algo, runs in sorted(left_out.items()) if algo not in algos
        },
        "data_efficiency": {},
        "inference": {},
        "optim": {},
    }
    for algo, runs in sorted(algos.items()):
        if runs[0].kind not in GENERATIONAL:
            continue
        eff = data_efficiency(runs, level, ppo["env_steps"]) if level is not None else None
        if eff is not None:
            summary["data_efficiency"][algo] = eff
        infer = inference_energy(runs, n, m)
        summary["inference"][algo] = infer
        summary["optim"][algo] = optim_energy(runs, infer, eff, ppo["e_ppo"])
    return summary


def _table(header: Sequence[str], rows: Sequence[Sequence[Any]]) -> list[str]:
    lines = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return lines


def _budget(budget: dict[str, Any]) -> str:
    """The GA budget of a method, marked where it differs from the paper's."""
    text = ", ".join(f"{k}={v}" for k, v in budget.items())
    differs = [k for k, v in budget.items() if PAPER_BUDGET.get(k, v) != v]
    return f"{text} (not the paper's: {', '.join(differs)})" if differs else text


def level_text(level: float | None) -> str:
    """A PPO level R as every report prints it: two decimals, or ``none``."""
    return "none" if level is None else f"{level:.2f}"


def _ratio(value: float | None) -> str:
    return "-" if value is None else f"**{value:.1f}**"


def _progress_list(entries: Sequence[dict[str, Any]]) -> str:
    return "; ".join(f"seed {e['seed']} ({e['progress']})" for e in entries)


def pooling_notes(s: dict[str, Any]) -> list[str]:
    """What each method's curve pools and what it leaves out: runs that stopped early, rows cut."""
    out = []
    for algo, m in s["methods"].items():
        if m["unfinished_pooled"]:
            out.append(
                f"- **{algo}: no run reached its budget**; its curve and numbers pool every run over the "
                f"{m['rows']} {'generations' if m['kind'] in GENERATIONAL else 'iterations'} all of them reached: {_progress_list(m['unfinished_pooled'])}."
            )
        elif m["longer"]:
            went_on = "; ".join(f"seeds {g['seeds']} to {g['rows']}" for g in m["longer"])
            out.append(
                f"- {algo}: runs of different lengths; the curve and numbers are cut at the {m['rows']} every run "
                f"reached ({went_on}: the dashed line)."
            )
        if m["left_out"]:
            out.append(
                f"- {algo}: left out (stopped before their budget): {_progress_list(m['left_out'])}; "
                f"pooled: seeds {m['seeds']}."
            )
    for algo, entries in s.get("left_out", {}).items():
        out.append(f"- {algo}: no run reached its budget, none pooled: {_progress_list(entries)}.")
    for algo, entries in s.get("duplicates", {}).items():
        repeated = "; ".join(f"seed {e['seed']} ({e['path']})" for e in entries)
        out.append(f"- {algo}: a seed run more than once counts once (its first run by path); left out: {repeated}.")
    mixed = [algo for algo in s["methods"] if " (" in algo]
    if mixed:
        out.append(
            f"- runs of one method with different results-affecting configs are listed apart: {', '.join(mixed)}."
        )
    return out + [""] if out else []


def methods_welch(a: dict[str, Any], b: dict[str, Any]) -> TTest:
    """Welch's two-sided test of two methods' final returns (:func:`method_summary`s of 2 seeds or more each)."""
    return welch(
        a["final_return_mean"],
        a["final_return_sd"],
        len(a["seeds"]),
        b["final_return_mean"],
        b["final_return_sd"],
        len(b["seeds"]),
    )


def method_pairs(s: dict[str, Any]) -> list[str]:
    """Welch's two-sided test of each pair of a task's methods (2 seeds or more each) at their last pooled rows."""
    methods = [(algo, m) for algo, m in s["methods"].items() if len(m["seeds"]) >= 2]
    rows = []
    for i, (a, ma) in enumerate(methods):
        for b, mb in methods[i + 1 :]:
            test = methods_welch(ma, mb)
            diff = f"{ma['final_return_mean']:.2f} - {mb['final_return_mean']:.2f} = {test.diff:+.2f}"
            rows.append([f"{a} vs {b}", f"{len(ma['seeds'])} / {len(mb['seeds'])}", diff, p_text(test.p)])
    if not rows:
        return []
    header = ["methods", "seeds", "difference of the final means", "Welch's t-test, two-sided"]
    return ["", "Methods against each other (each at its last pooled generation):", ""] + _table(header, rows)


def task_markdown(s: dict[str, Any], figure: str | None) -> list[str]:
    """The report section of one task: curves, final returns, Tables 1-4 of the paper."""
    out = [f"## {s['env_id']} (n={s['n']}, m={s['m']})", ""]
    out += [f"![learning curves]({figure})", ""] if s["methods"] and figure else []
    out += pooling_notes(s)
    if not s["methods"]:
        return out
    level = s["ppo_level"]
    out.append(f"PPO level R: {level_text(level)} ({s['ppo_level_source']}).")
    if not any(m["kind"] == "ppo" for m in s["methods"].values()):
        out.append("No PPO run found for this task: the PPO curve and a measured E_PPO are missing.")
    out.append("")
    rows = [
        [
            algo,
            m["kind"],
            _budget(m["budget"]),
            len(m["seeds"]),
            m["rows"],
            sig(m["total_env_steps"]),
            f"{m['final_return_mean']:.2f} +- {m['final_return_std']:.2f}",
        ]
        for algo, m in s["methods"].items()
    ]
    out += _table(
        [
            "method",
            "kind",
            "budget",
            "seeds",
            "generations / iterations pooled",
            "env steps (mean)",
            "return at the last pooled generation, mean +- std over seeds",
        ],
        rows,
    )
    out += method_pairs(s)
    out += ["", "### Data efficiency (paper Table: R, G, E, gamma)", ""]
    if level is None:
        out.append("Not computed: no PPO level (run dpn_ppo or pass --ppo-level).")
    else:
        rows = [
            [
                algo,
                level_text(level),
                e["G"] if e["G"] is not None else "not reached",
                sig(e["E"]),
                "-" if e["gamma"] is None else f"**{e['gamma']:.2f}**",
                f"{e['seeds_reaching']}/{e['seeds']}",
            ]
            for algo, e in s["data_efficiency"].items()
        ]
        out += _table(["method", "R", "G", "E (env steps)", "gamma = E / PPO steps", "seeds reaching R"], rows)
        out += [
            "",
            f"G: first generation of the mean-over-seeds curve at R; E: env steps actually used up to G (mean over seeds); "
            f"PPO steps = {sig(s['ppo']['env_steps'])}.",
        ]
    out += ["", "### Inference energy (paper Table: E_DPN vs E_SPN, pJ per env step)", ""]
    rows = [
        [
            algo,
            f"{i['rate_per_sim_step']:.4f}",
            f"{i['rate_per_env_step']:.4f}",
            sig(i["e_dpn"]),
            sig(i["e_spn_dense"]),
            _ratio(i["ratio_dense"]),
            f"{sig(i['synapses_l1'])} / {sig(i['synapses_l2'])}",
            sig(i["e_spn_mask"]),
            _ratio(i["ratio_mask"]),
        ]
        for algo, i in s["inference"].items()
    ]
    out += _table(
        [
            "method",
            "rate / sim step",
            "rate / env step",
            "E_DPN",
            "E_SPN dense (paper)",
            "E_DPN / E_SPN dense",
            "synapses l1 / l2 (mask-aware)",
            "E_SPN mask-aware",
            "E_DPN / E_SPN mask-aware",
        ],
        rows,
    )
    out += [
        "",
        "E_SPN uses the final elites' rate per simulation step (the reading the paper's numbers fit); "
        "dense counts every synapse as the paper does, mask-aware only the existing ones.",
    ]
    out += [
        "",
        "### Optimisation energy (paper Table: E_PPO vs E_GA, pJ)",
        "",
        f"E_PPO = {sig(s['ppo']['e_ppo'])}: {s['ppo']['source']}.",
        "",
    ]
    rows = [
        [
            algo,
            f"{sig(o['env_steps'])} ({o['steps_source']})",
            sig(s["ppo"]["e_ppo"]),
            sig(o["e_ga_dense"]),
            _ratio(o["ratio_dense"]),
            sig(o["e_ga_mask"]),
            _ratio(o["ratio_mask"]),
        ]
        for algo, o in s["optim"].items()
    ]
    out += _table(
        [
            "method",
            "env steps counted",
            "E_PPO",
            "E_GA dense (paper)",
            "E_PPO / E_GA dense",
            "E_GA mask-aware",
            "E_PPO / E_GA mask-aware",
        ],
        rows,
    )
    return out + [""]


def summarize(
    paths: Sequence[str | Path],
    out: Path,
    level: float | None = None,
    strict: bool = False,
    fallback_levels: dict[str, tuple[float, str]] | None = None,
    published: dict[str, dict[str, tuple[int, float, float]]] | None = None,
    seeds: Collection[int] | None = None,
) -> tuple[list[RunRecord], dict[str, Any], dict[str, str]]:
    """Find the runs under ``paths``, pool them per task and method (``strict``: finished runs only; ``seeds``:
    only the runs of those seeds, though every run found is returned), draw one figure per task into ``out``;
    ``(runs, {env: summary}, {env: figure path})``.

    R per task: ``level`` if given, else the task's DPN-PPO runs, else ``fallback_levels[env]`` (value, source; the
    source's words before " (" label the figure's line).
    ``published[env][algo]`` = (generation, mean, std) is drawn on the figure as a marker.
    """
    runs = find_runs(paths)
    if not runs:
        raise SpnError(
            f"no run found under {', '.join(map(str, paths))}: a run directory holds progress.csv and "
            ".hydra/config.yaml (or config.yaml)"
        )
    out.mkdir(parents=True, exist_ok=True)
    summaries: dict[str, Any] = {}
    figures: dict[str, str] = {}
    chosen = runs if seeds is None else [run for run in runs if run.seed in seeds]
    for env, algos in group_runs(chosen).items():
        repeats: dict[str, list[RunRecord]] = {}
        for algo in algos:
            algos[algo], repeated = split_duplicates(algos[algo])
            if repeated:
                repeats[algo] = repeated
        pools, left = choose_pools(algos, strict)
        task_level, source, note = level, "--ppo-level", ""
        if task_level is None and PPO_LEVEL_ALGO not in pools and env in (fallback_levels or {}):
            task_level, source = fallback_levels[env]
            note = source.split(" (")[0]
        summary = task_summary(env, pools, task_level, source, left)
        summary["duplicates"] = {algo: [left_out_entry(run) for run in rs] for algo, rs in sorted(repeats.items())}
        summaries[env] = summary
        if pools:
            reached = {algo: e["G"] for algo, e in summary["data_efficiency"].items()}
            marks = (published or {}).get(env)
            figure = task_figure(
                summary["env_id"], pools, summary["ppo_level"], out / f"{env}.png", reached, marks, note
            )
            figures[env] = str(figure)
    return runs, summaries, figures


def stopped_lines(runs: Sequence[RunRecord]) -> list[str]:
    """The runs that did not reach their budget, one line each (env, method, seed, how far, where)."""
    stopped = [run for run in runs if not run.finished]
    if not stopped:
        return []
    lines = [f"Runs that did not reach their budget ({len(stopped)}), never pooled with finished runs:", ""]
    lines += [f"- {r.env} {r.algo} seed {r.seed}: {r.progress_text} ({shown_path(r.path)})" for r in stopped]
    return lines + [""]


def preface_lines(out: Path, preface: Path | None = None) -> list[str]:
    """The hand-written text a report starts with: ``preface`` (default ``out/PREFACE.md``) if it is a file."""
    preface = out / "PREFACE.md" if preface is None else Path(preface)
    return [preface.read_text().rstrip(), ""] if preface.is_file() else []


def build_report(paths: Sequence[str | Path], out: Path, level: float | None = None) -> dict[str, Any]:
    """Find the runs under ``paths``, write report.md (after ``out/PREFACE.md``, if there is one), report.json and
    figures into ``out``; return the numbers."""
    runs, summaries, figures = summarize(paths, out, level)
    lines = preface_lines(out)
    lines += ["# SPN report", "", f"Runs found under {', '.join(map(str, paths))}: {len(runs)}.", ""]
    lines += stopped_lines(runs)
    if not any(run.kind == "ppo" for run in runs):
        lines += [
            "No PPO run found: PPO curves, the DPN-PPO level and measured PPO pass counts are missing "
            "(E_PPO below is the paper's model with its published counts, labelled as such).",
            "",
        ]
    lines += ["Energy model: e_MAC = 4.6 pJ, e_AC = 0.9 pJ (45 nm); see spn_torchrl/energy.py and SPEC.md.", ""]
    for env, summary in summaries.items():
        lines += task_markdown(summary, f"{env}.png")
    (out / "report.md").write_text("\n".join(lines))
    (out / "report.json").write_text(json.dumps(summaries, indent=2, default=float))
    backends = {run.config.get("logger", {}).get("backend") for run in runs}
    return {
        "tasks": summaries,
        "figures": figures,
        "markdown": str(out / "report.md"),
        "stopped": [left_out_entry(run) | {"env": run.env, "algo": run.algo} for run in runs if not run.finished],
        "wandb_projects": sorted({str(run.config.logger.project) for run in runs}) if backends == {"wandb"} else [],
    }


def log_to_wandb(result: dict[str, Any], project: str) -> None:
    """The report's figures (wandb.Image) and tables (wandb.Table) to W&B; offline without credentials."""
    import wandb

    from spn_torchrl.records import wandb_mode

    os.environ.setdefault("WANDB_SILENT", "true")
    run = wandb.init(
        project=project, job_type="report", mode=wandb_mode("auto"), dir=str(Path(result["markdown"]).parent)
    )
    try:
        for env, s in result["tasks"].items():
            payload: dict[str, Any] = {}
            if env in result["figures"]:
                payload[f"report/{env}/curves"] = wandb.Image(result["figures"][env])
            for section in ("data_efficiency", "inference", "optim"):
                columns = sorted({k for v in s[section].values() for k in v if not isinstance(v[k], list)})
                data = [[algo] + [v.get(k) for k in columns] for algo, v in s[section].items()]
                if data:
                    payload[f"report/{env}/{section}"] = wandb.Table(columns=["method"] + columns, data=data)
            run.log(payload)
    finally:
        run.finish()
