"""The authors' published generation-100 elites replayed on the paper's simulator (v2) and on ours (v5): a table.

    PYTHONPATH=$PWD python scripts/published_elites_v2_v5.py [--task HalfCheetah] [--variants Connections,Weights]
        [--episodes 10] [--reference /work/shared/reference]

For each published seed, the authors' logged generation-100 return (their ``*_elite_returns_by_gen.csv``) beside
the elite's mean over ``--episodes`` fresh episodes (env seeds 0..episodes-1, python -m spn_torchrl.tools.published)
on env.backend=gym_v2 (``<Task>-v2``), mujoco_batch (``<Task>-v5``) and mujoco_batch_mj210 (``<Task>-v5`` with
MuJoCo 2.1's inertias), then the mean and std (ddof=0) over seeds and each backend's mean over the logged one.
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

from spn_torchrl.tools.published import replay

BACKENDS = (("gym_v2", "v2"), ("mujoco_batch", "v5"), ("mujoco_batch_mj210", "v5"))


def logged_final(path: Path) -> dict[int, float]:
    """``{published seed: logged return at the last generation}`` from an ``*_elite_returns_by_gen.csv``."""
    with open(path, newline="") as f:
        last = list(csv.DictReader(f))[-1]
    return {int(k.removeprefix("seed_")): float(v) for k, v in last.items() if k.startswith("seed_")}


def table(task: str, variant: str, episodes: int, reference: Path) -> None:
    """Print one variant's markdown table: seeds by row, the logged return and each backend's replay."""
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
    print("| wall time (s) | - | " + " | ".join(f"{seconds[b]:.0f}" for b, _ in BACKENDS) + " |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="HalfCheetah", choices=("HalfCheetah", "Swimmer"))
    parser.add_argument("--variants", default="Connections,Weights", help="Connections, Weights or both")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--reference", type=Path, default=Path("/work/shared/reference"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    for variant in args.variants.split(","):
        table(args.task, variant, args.episodes, args.reference)


if __name__ == "__main__":
    main()
