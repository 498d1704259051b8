"""Env steps/s of a GA generation on env.backend=gym_v2 (Gym 0.21 + mujoco-py, MuJoCo 2.1.0) against mujoco_batch
on the v5 task, and the wall time of a paper-budget seed at each rate.

    python benchmarks/gym_v2_throughput.py --task HalfCheetah --population 200 [--layouts 1x1,1x2,2x1]

A layout PxW is P evaluator processes (evaluator.processes) of W threads each (env.threads: gym_v2's worker
processes, mujoco_batch's physics threads). Each row times one steady-state generation (the N children and the
previous generation's top 10 x 10 re-evaluation in one rollout, then selection: benchmarks/throughput.py's
timed_generation) and prints its env steps/s, its ratio to mujoco_batch's rate under the same layout and the hours of
a paper-budget seed (3e7 env steps). Needs the gym_v2 venv (bash scripts/make_gym_v2_env.sh).
"""

from __future__ import annotations

import argparse

import torch
from throughput import PAPER_STEPS, generation  # benchmarks/throughput.py, beside this script


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--task", default="HalfCheetah", choices=("HalfCheetah", "Swimmer", "HumanoidStandup"))
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--layouts", default="1x1,1x2,2x1", help="PxW layouts, comma-separated")
    parser.add_argument("--episode-steps", type=int, default=1000)
    args = parser.parse_args()
    torch.set_num_threads(1)
    layouts = [tuple(int(x) for x in layout.split("x")) for layout in args.layouts.split(",")]
    print(f"{args.task}, population {args.population} (+ re-evaluation), episodes of {args.episode_steps} steps")
    print(
        "| layout (processes x threads) | backend | env id | env steps/s | ratio to mujoco_batch | paper-budget seed (h) |"
    )
    print("|---|---|---|---|---|---|")
    for processes, threads in layouts:
        rates = {}
        for backend, version in (("mujoco_batch", "v5"), ("gym_v2", "v2")):
            env_id = f"{args.task}-{version}"
            g = generation(env_id, backend, args.population, threads, args.episode_steps, processes)
            rates[backend] = g.steps_per_s
            ratio = g.steps_per_s / rates["mujoco_batch"]
            print(
                f"| {processes}x{threads} | {backend} | {env_id} | {g.steps_per_s:,.0f} | {ratio:.2f} "
                f"| {PAPER_STEPS / g.steps_per_s / 3600:.1f} |",
                flush=True,
            )


if __name__ == "__main__":
    main()
