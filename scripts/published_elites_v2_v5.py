"""The authors' published generation-100 elites replayed on the paper's simulator (v2) and on ours (v5): a table.

    PYTHONPATH=$PWD python scripts/published_elites_v2_v5.py [--task HalfCheetah] [--variants Connections,Weights]
        [--episodes 10] [--reference /work/shared/reference] [--same-states]

For each published seed, the authors' logged generation-100 return (their ``*_elite_returns_by_gen.csv``) beside
the elite's mean over ``--episodes`` fresh episodes (env seeds 0..episodes-1, python -m spn_torchrl.tools.published)
on env.backend=gym_v2 (``<Task>-v2``), mujoco_batch (``<Task>-v5``) and mujoco_batch_mj210 (``<Task>-v5`` with
MuJoCo 2.1's inertias), then the mean and std (ddof=0) over seeds, each backend's mean over the logged one, and
each v5 backend's paired t-test against gym_v2 over the elites (per variant, then pooled): the test that decides
whether a fast backend stands in for gym_v2 in the v2 seeds.
Reads the reference data at run time; nothing of it is stored in the repository. Needs the gym_v2 venv
(bash scripts/make_gym_v2_env.sh).
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
import torch

from spn_torchrl.analysis.stats import p_text, paired
from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.envs.mujoco210 import MJ210_TASKS
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import build_spn
from spn_torchrl.tools.published import genome_kind_of, load_published, replay

BACKENDS = (("gym_v2", "v2"), ("mujoco_batch", "v5"), ("mujoco_batch_mj210", "v5"))


def logged_final(path: Path) -> dict[int, float]:
    """``{published seed: logged return at the last generation}`` from an ``*_elite_returns_by_gen.csv``."""
    with open(path, newline="") as f:
        last = list(csv.DictReader(f))[-1]
    return {int(k.removeprefix("seed_")): float(v) for k, v in last.items() if k.startswith("seed_")}


def paired_row(label: str, replays: dict[str, list[float]]) -> str:
    """A table row: each v5 backend's paired t-test against gym_v2 over the elites (mean difference, p)."""
    cells = []
    for backend, _ in BACKENDS[1:]:
        test = paired([a - b for a, b in zip(replays[backend], replays["gym_v2"], strict=True)])
        cells.append(f"{test.diff:+.1f}, {p_text(test.p)}")
    return f"| {label} | - | - | " + " | ".join(cells) + " |"


def table(task: str, variant: str, episodes: int, reference: Path) -> dict[str, list[float]]:
    """Print one variant's markdown table: seeds by row, the logged return and each backend's replay, and each v5
    backend's paired test against gym_v2; return each backend's replays in seed order."""
    logged = logged_final(reference / f"{task}-v2_SPN_{variant}_elite_returns_by_gen.csv")
    npz = reference / f"{task}-v2_SPN_{variant}_gen100_elites.npz"
    replays, seconds = {}, {}
    for backend, version in BACKENDS:
        t0 = time.perf_counter()
        replays[backend] = replay(npz, f"{task}-{version}", episodes, 0, backend)
        seconds[backend] = time.perf_counter() - t0
    seeds = sorted(logged)
    print(f"\n{task} {variant}-GA, published generation-100 elites, {episodes} fresh episodes each (env seeds 0..)")
    head = ["published seed", "authors' log (gen. 100)"] + [f"{b} ({task}-{v})" for b, v in BACKENDS]
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for s in seeds:
        print(f"| {s} | {logged[s]:.1f} | " + " | ".join(f"{replays[b][s]:.1f}" for b, _ in BACKENDS) + " |")
    columns = [np.array([logged[s] for s in seeds])] + [np.array([replays[b][s] for s in seeds]) for b, _ in BACKENDS]
    print("| mean +- std | " + " | ".join(f"{c.mean():.1f} +- {c.std():.1f}" for c in columns) + " |")
    ratios = [f"{c.mean() / columns[0].mean():.3f}" for c in columns[1:]]
    print("| mean / logged mean | 1 | " + " | ".join(ratios) + " |")
    ordered = {b: [replays[b][s] for s in seeds] for b, _ in BACKENDS}
    print(paired_row("paired t vs gym_v2 over the elites (mean diff, p)", ordered))
    print("| wall time (s) | - | " + " | ".join(f"{seconds[b]:.0f}" for b, _ in BACKENDS) + " |")
    return ordered


def start_from(env, backend: str, qpos: np.ndarray, qvel: np.ndarray) -> None:
    """Make every reset of ``env`` (``backend`` gym_v2 or mujoco_batch_mj210) put its slots in ``qpos``, ``qvel``."""
    if backend == "gym_v2":  # Gym's own set_state in the workers
        env._reset_slots = lambda ids: env.set_state(qpos, qvel)
    else:
        env._reset_slots = lambda ids: (env.sims.reset(None, qpos, qvel), env._write_obs(None))


def same_states(task: str, variant: str, episodes: int, reference: Path) -> None:
    """Print each published elite's mean return from the same ``episodes`` initial states on gym_v2,
    mujoco_batch_mj210 and mujoco_batch, each v5 backend's largest difference of one episode's return from gym_v2,
    and the means over the elites."""
    npz = reference / f"{task}-v2_SPN_{variant}_gen100_elites.npz"
    spec = task_spec(f"{task}-v5")
    envs = {"gym_v2": make_batched_env(MJ210_TASKS[spec.env_id], episodes, backend="gym_v2")}
    for backend in ("mujoco_batch_mj210", "mujoco_batch"):
        envs[backend] = make_batched_env(spec.env_id, episodes, backend=backend)
    try:
        m, rng = envs["mujoco_batch"].model, np.random.default_rng(0)
        qpos = m.qpos0 + rng.uniform(-0.1, 0.1, (episodes, m.nq))
        qvel = rng.uniform(-0.1, 0.1, (episodes, m.nv))
        for backend, env in envs.items():
            start_from(env, backend, qpos, qvel)
        print(f"\n{task} {variant}-GA, published elites from the same {episodes} initial states (mean return)")
        print(
            "| published seed | gym_v2 | mujoco_batch_mj210 | mujoco_batch | max abs episode difference from gym_v2: "
            "mj210, mujoco_batch |"
        )
        print("|---|---|---|---|---|")
        means: dict[str, list[float]] = {b: [] for b in envs}
        for s, (genome, w1, w2) in load_published(npz).items():
            spn = build_spn(
                torch.as_tensor(w1),
                torch.as_tensor(w2),
                genome_kind=genome_kind_of(npz),
                discrete=False,
                action_low=spec.action_low,
                action_high=spec.action_high,
            )
            genomes = torch.as_tensor(genome, dtype=torch.float32).reshape(1, -1).expand(episodes, -1)
            returns = {
                b: PopulationEvaluator(env, spn, spec.max_episode_steps)(genomes, 0).returns.numpy()
                for b, env in envs.items()
            }
            for b, r in returns.items():
                means[b].append(float(r.mean()))
            diffs = [
                f"{np.abs(returns[b] - returns['gym_v2']).max():.2g}" for b in ("mujoco_batch_mj210", "mujoco_batch")
            ]
            print(f"| {s} | " + " | ".join(f"{r.mean():.2f}" for r in returns.values()) + f" | {', '.join(diffs)} |")
        print("| mean | " + " | ".join(f"{np.mean(v):.2f}" for v in means.values()) + " | |")
    finally:
        for env in envs.values():
            env.close()


def task_label(task: str, variants: list[str]) -> str:
    """``HalfCheetah, Connections-GA and Weights-GA``."""
    return f"{task}, " + " and ".join(f"{v}-GA" for v in variants)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="HalfCheetah", choices=("HalfCheetah", "Swimmer"))
    parser.add_argument("--variants", default="Connections,Weights", help="Connections, Weights or both")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--reference", type=Path, default=Path("/work/shared/reference"))
    parser.add_argument("--same-states", action="store_true", help="gym_v2 and mujoco_batch_mj210 from equal states")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.same_states:
        for variant in args.variants.split(","):
            same_states(args.task, variant, args.episodes, args.reference)
        return
    pooled: dict[str, list[float]] = {b: [] for b, _ in BACKENDS}
    variants = args.variants.split(",")
    for variant in variants:
        for backend, values in table(args.task, variant, args.episodes, args.reference).items():
            pooled[backend] += values
    if len(variants) > 1:
        print(f"\n{task_label(args.task, variants)}: every elite pooled, paired t against gym_v2")
        print("| | | | " + " | ".join(f"{b}" for b, _ in BACKENDS[1:]) + " |\n|---|---|---|---|---|")
        print(paired_row(f"{len(pooled['gym_v2'])} elites (mean diff, p)", pooled))


if __name__ == "__main__":
    main()
