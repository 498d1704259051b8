"""Env steps/s of one lockstep generation of R runs (R x (N + 10 x 10) slots) against its physics alone.

    python benchmarks/lockstep.py --backend mujoco_warp --device cuda --env HalfCheetah-v5 --runs 1,7,10,66 \
        --population 200 --episode-steps 100 [--profile 20]
    python benchmarks/lockstep.py --backend mujoco_batch --env Swimmer-v5 --runs 1,2 --population 8 --episode-steps 50

Per R it prints: env steps/s of one lockstep generation (R populations and their elite re-evaluations in one
rollout (selection, milliseconds, left out), each genome on its run's fixed weights, as spn_torchrl.training.lockstep runs it), of its physics alone
(mujoco_warp: the captured substeps of every world with random controls; mujoco_batch: the batched physics
call's share of the same generation), their ratio, peak memory (device: torch's peak allocation plus Warp's
pool's peak; CPU: this process's resident peak), and the wall time of the paper's 10 seeds of 100 generations at
this N (ceil(10 / R) lockstep batches of 100 generations at this generation's time, 1000-step episodes scaled
from the cut; for R > 10 the time of R seeds, an upper bound). ``--profile S`` runs torch.profiler over S env
steps of the device loop at the last R and prints its top operations. benchmarks/gpu_lockstep.sh runs the GPU
measurement of issue 48 in under 8 minutes.
"""

from __future__ import annotations

import argparse
import gc
import math
import resource
import time

import numpy as np
import torch
from throughput import elite_slots, physics_rate, synchronize

from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.envs.mujoco_warp import MujocoWarpEnv, torch_device
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import PopulationSPN, init_fixed_weights
from spn_torchrl.training import ga

SEEDS, GENERATIONS, EPISODE = 10, 100, 1000  # the paper's seeds per task, generations and episode length


def lockstep_spn(env_id: str, runs: int) -> PopulationSPN:
    """The SPN of ``runs`` runs, each with its own Kaiming weights (seeds 0..R-1)."""
    spec = task_spec(env_id)
    pairs = [init_fixed_weights(spec.n_obs, spec.n_act, 64, torch.Generator().manual_seed(r)) for r in range(runs)]
    w1, w2 = (torch.stack(w) for w in zip(*pairs))
    return PopulationSPN(w1, w2, discrete=spec.discrete, action_low=spec.action_low, action_high=spec.action_high)


def generation_batch(spn: PopulationSPN, runs: int, population: int) -> tuple[torch.Tensor, np.ndarray, np.ndarray]:
    """Genomes, env seeds and run indices of one lockstep generation: each run's N children and its 10 x 10
    re-evaluation."""
    gen = torch.Generator().manual_seed(0)
    per_run = population + elite_slots(population)
    genomes = ga.initial_population(runs * per_run + runs * per_run % 2, spn.genome_size, 0.01, gen)[: runs * per_run]
    return genomes, np.arange(runs * per_run), np.repeat(np.arange(runs), per_run)


def peak_memory_mb(env) -> float:
    if isinstance(env, MujocoWarpEnv) and env.device.type == "cuda":
        wp = env._wp
        pool = wp.get_mempool_used_mem_high(env.wp_device) if wp.is_mempool_enabled(env.wp_device) else 0
        return (torch.cuda.max_memory_allocated(env.device) + pool) / 2**20
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def measure(args: argparse.Namespace, runs: int) -> dict:
    spn = lockstep_spn(args.env, runs)
    genomes, seeds, run_index = generation_batch(spn, runs, args.population)
    slots = genomes.shape[0]
    device = args.device if args.backend == "mujoco_warp" else "cpu"
    if device.startswith("cuda"):
        torch.cuda.reset_peak_memory_stats(device)
    env = make_batched_env(args.env, slots, backend=args.backend, threads=args.threads, device=device)
    evaluator = PopulationEvaluator(env, spn, args.episode_steps)
    try:
        evaluator(genomes, seeds, runs=run_index)  # warm: kernels, caches
        before = getattr(env, "physics_seconds", None)
        t0 = time.perf_counter()
        result = evaluator(genomes, seeds, runs=run_index)
        seconds = time.perf_counter() - t0
        rate = result.total_steps / seconds
        if isinstance(env, MujocoWarpEnv):
            physics = physics_rate(env, args.physics_steps)
        elif before is not None:
            physics = result.total_steps / (env.physics_seconds - before)
        else:
            physics = math.nan  # cartpole_batch: its numpy step is the whole env
        if args.profile and isinstance(env, MujocoWarpEnv):
            profile(evaluator, genomes, seeds, run_index, args.profile)
        memory = peak_memory_mb(env)
    finally:
        evaluator.close()
    batches = math.ceil(SEEDS / runs)
    paper_wall = batches * GENERATIONS * seconds * EPISODE / args.episode_steps
    return dict(runs=runs, slots=slots, rate=rate, physics=physics, memory=memory, paper_wall=paper_wall)


def profile(evaluator: PopulationEvaluator, genomes, seeds, run_index, steps: int) -> None:
    """torch.profiler over ``steps`` env steps of the device loop: where a step's time goes."""
    from torch.profiler import ProfilerActivity
    from torch.profiler import profile as torch_profile

    activities = [ProfilerActivity.CPU] + ([ProfilerActivity.CUDA] if torch.cuda.is_available() else [])
    cut, evaluator.max_episode_steps = evaluator.max_episode_steps, steps
    try:
        with torch_profile(activities=activities) as prof:
            evaluator(genomes, seeds, runs=run_index)
            synchronize(evaluator.env)
    finally:
        evaluator.max_episode_steps = cut
    key = "cuda_time_total" if torch.cuda.is_available() else "cpu_time_total"
    print(prof.key_averages().table(sort_by=key, row_limit=20), flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="HalfCheetah-v5")
    parser.add_argument("--backend", default="mujoco_warp", choices=("mujoco_warp", "mujoco_batch", "cartpole_batch"))
    parser.add_argument("--device", default="cuda", help="mujoco_warp: cpu, cuda or cuda:<index>")
    parser.add_argument("--runs", default="1,10", help="comma-separated R: runs in lockstep")
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--episode-steps", type=int, default=100)
    parser.add_argument("--physics-steps", type=int, default=50, help="mujoco_warp: env steps of the physics run")
    parser.add_argument("--threads", type=int, default=1, help="mujoco_batch: physics threads")
    parser.add_argument("--profile", type=int, default=0, help="mujoco_warp: env steps to profile at the last R")
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.backend == "mujoco_warp":
        args.device = str(torch_device(args.device))
    where = args.device if args.backend == "mujoco_warp" else "cpu"
    print(f"{args.backend} on {where}, {args.env}, N={args.population}, {args.episode_steps}-step episodes")
    print(
        "| R | slots | lockstep generation (env steps/s) | physics alone (env steps/s) | ratio | peak memory (MB) | "
        f"paper's {SEEDS} seeds x {GENERATIONS} generations |"
    )
    print("|---|---|---|---|---|---|---|")
    all_runs = [int(r) for r in args.runs.split(",")]
    for runs in all_runs:
        keep = args.profile
        args.profile = keep if runs == all_runs[-1] else 0
        m = measure(args, runs)
        args.profile = keep
        print(
            f"| {m['runs']} | {m['slots']:,} | {m['rate']:,.0f} | {m['physics']:,.0f} | {m['rate'] / m['physics']:.3f} "
            f"| {m['memory']:,.0f} | {m['paper_wall'] / 60:,.1f} min |",
            flush=True,
        )
        gc.collect()


if __name__ == "__main__":
    main()
