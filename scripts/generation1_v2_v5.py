"""The paper's generation-1 protocol on v2 and v5 with the same inputs: the authors' fixed weights and ours.

    PYTHONPATH=$PWD python scripts/generation1_v2_v5.py [--seeds 0-9] [--weights authors,ours] [--versions v2,v5]
        [--runs reproduction/runs] [--reference /work/shared/reference] [--threads 1]

For our run seed S (0-9) of HalfCheetah Connections-GA, from its committed config (``--runs``/halfcheetah__conn_ga__S):
the generation-0 population that train.py draws (100 mirrored pairs of scores, i.e. of complementary masks), the
fitness of one episode each on train.py's generation-1 env seeds, the top 10 re-evaluated for 10 episodes on its
re-evaluation seeds, and the best 10-episode mean: generation 1's logged return (SPEC.md). The same masks and env
seeds run with two sets of fixed weights, the authors' (``w1_seed_P``, ``w2_seed_P`` of the published seed
P = 10 (S + 1)) and ours (the run's own), each on HalfCheetah-v2 (env.backend=gym_v2: Gym 0.21, MuJoCo 2.1) and
HalfCheetah-v5 (mujoco_batch). The table puts them beside the authors' logged generation 1 of seed P and our
committed generation-1 row of seed S, which "ours, v5" must equal (train.py's generation 1 on the same networks).
Reads the reference data at run time; nothing of it is stored in the repository. Each cell is 3e5 env steps.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
import torch

from spn_torchrl.config import from_saved
from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.records import read_progress
from spn_torchrl.seeds import FITNESS, REEVALUATION, episode_seeds
from spn_torchrl.snn.policies import spn_from_config
from spn_torchrl.tools.published import load_published
from spn_torchrl.training import ga
from spn_torchrl.training.evolve import initial_state

BACKENDS = {"v2": "gym_v2", "v5": "mujoco_batch"}
WEIGHTS = {"authors": "authors' weights", "ours": "our weights"}


def generation_one(
    env_id: str, backend: str, cfg, w1: torch.Tensor, w2: torch.Tensor, population: torch.Tensor, threads: int
) -> dict[str, float]:
    """Generation 1 of ``population`` with fixed weights ``w1``, ``w2`` on ``env_id``: the logged return (best
    10-episode mean of the top 10), the best and the mean single-episode fitness."""
    algo, spec = cfg.algo, task_spec(env_id)
    spn = spn_from_config(algo.snn, algo.genome, spec, w1, w2)
    k, episodes, n = algo.elite_candidates, algo.elite_episodes, algo.population
    env = make_batched_env(env_id, n, backend=backend, threads=threads)
    try:
        evaluate = PopulationEvaluator(env, spn, spec.max_episode_steps)
        fitness = evaluate(population, episode_seeds(cfg.seed, 1, FITNESS, n)).returns
        candidates = ga.elite_candidates(fitness, k)
        genomes = ga.reevaluation_genomes(population, candidates, episodes)
        reeval = evaluate(genomes, episode_seeds(cfg.seed, 1, REEVALUATION, k * episodes)).returns
    finally:
        env.close()
    _, elite = ga.pick_elite(candidates, reeval.view(k, episodes))
    return {"elite": elite, "best": float(fitness.max()), "mean": float(fitness.mean())}


def logged_first(path: Path) -> dict[int, float]:
    """``{published seed: logged return at generation 1}`` from an ``*_elite_returns_by_gen.csv``."""
    with open(path, newline="") as f:
        first = next(iter(csv.DictReader(f)))
    return {int(k.removeprefix("seed_")): float(v) for k, v in first.items() if k.startswith("seed_")}


def seed_list(text: str) -> list[int]:
    """``0-9`` or ``0,3,5`` -> seeds."""
    if "-" in text:
        low, high = map(int, text.split("-"))
        return list(range(low, high + 1))
    return [int(s) for s in text.split(",")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=seed_list, default=list(range(10)), help="our run seeds: 0-9 or 0,3")
    parser.add_argument("--weights", default="authors,ours")
    parser.add_argument("--versions", default="v2,v5")
    parser.add_argument("--runs", type=Path, default=Path("reproduction/runs"))
    parser.add_argument("--reference", type=Path, default=Path("/work/shared/reference"))
    parser.add_argument("--threads", type=int, default=1, help="env.threads (gym_v2: worker processes)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    weights, versions = args.weights.split(","), args.versions.split(",")
    published = load_published(args.reference / "HalfCheetah-v2_SPN_Connections_gen100_elites.npz")
    logged = logged_first(args.reference / "HalfCheetah-v2_SPN_Connections_elite_returns_by_gen.csv")
    cells = [(w, v) for w in weights for v in versions]
    head = ["seed S (published P)", "authors' log, gen. 1 (P)"] + [f"{WEIGHTS[w]}, {v}" for w, v in cells]
    head += ["our committed row, gen. 1 (S, v5)"]
    print("HalfCheetah Connections-GA, generation 1 (elite: best 10-episode mean of the top 10; mean fitness)")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head), flush=True)
    columns: dict[str, list[float]] = {h: [] for h in head[1:]}
    seconds = {f"{WEIGHTS[w]}, {v}": 0.0 for w, v in cells}
    for s in args.seeds:
        run_dir = args.runs / f"halfcheetah__conn_ga__{s}"
        cfg = from_saved((run_dir / "config.yaml").read_text())
        state = initial_state(cfg.algo, task_spec(cfg.env.id), cfg.seed)
        p = 10 * (s + 1)
        _, w1_authors, w2_authors = published[p]
        fixed = {
            "ours": (state["w1"], state["w2"]),
            "authors": (torch.as_tensor(w1_authors), torch.as_tensor(w2_authors)),
        }
        row = [f"{s} ({p})", f"{logged[p]:.1f}"]
        columns[head[1]].append(logged[p])
        for w, v in cells:
            t0 = time.perf_counter()
            g = generation_one(f"HalfCheetah-{v}", BACKENDS[v], cfg, *fixed[w], state["population"], args.threads)
            seconds[f"{WEIGHTS[w]}, {v}"] += time.perf_counter() - t0
            columns[f"{WEIGHTS[w]}, {v}"].append(g["elite"])
            row.append(f"{g['elite']:.1f} ({g['mean']:.0f})")
        committed = read_progress(run_dir / "progress.csv")[0]
        columns[head[-1]].append(float(committed["eval_return"]))
        row.append(f"{float(committed['eval_return']):.1f} ({float(committed['mean_fitness']):.0f})")
        print("| " + " | ".join(row) + " |", flush=True)
    means = [f"{np.mean(c):.1f} +- {np.std(c):.1f}" for c in columns.values()]
    print(f"| mean +- std over {len(args.seeds)} seeds | " + " | ".join(means) + " |")
    times = ["-"] + [f"{seconds[h]:.0f}" for h in head[2:-1]] + ["-"]
    print("| wall time (s) | " + " | ".join(times) + " |")


if __name__ == "__main__":
    main()
