"""Env steps/s of a GA generation against the physics ceiling and the paper's serial loop.

    python benchmarks/throughput.py --env HalfCheetah-v5 --population 200 [--processes 2 --threads 1]

(processes and threads default to the task's conf/env settings: 2 x 1 for HalfCheetah and Swimmer, 1 x 2 for
HumanoidStandup.)

Measures on the same cores: (a) the ceiling, batched physics only (one mujoco.batch on processes x threads
threads, random controls); (b) one GA generation per backend as spn_torchrl.training.evolve runs it with the default
evaluator (the population and the previous generation's elite re-evaluation in one rollout, then selection);
(c) the paper's way, one Gymnasium env and one single-policy SPN call per step that computes the masks (as
the authors' code did), on a short slice, and the same loop with masks computed once. The last line is
``ratio_to_ceiling=<x> speedup_vs_paper=<y>``.

    python benchmarks/throughput.py --backend mujoco_warp --device cuda --env HumanoidStandup-v5 \
        --populations 200,2000,20000 --episode-steps 1000

prints, per population N (the gpu extra; --device cpu runs Warp's CPU backend, for tiny sizes): env steps/s of
one GA generation on the device (N children and the top-10 x 10 re-evaluation in one rollout, then selection)
and of its physics alone (the captured substeps of every world, random controls, no policy), the device memory
(torch's peak allocation plus Warp's memory pool's peak), and the wall time of a paper-budget seed (3e7 env
steps) at the generation's rate.
"""

from __future__ import annotations

import argparse
import gc
import resource
import time
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch
from mujoco.batch import Batch
from omegaconf import DictConfig, OmegaConf

from spn_torchrl.config import LocalEvaluatorConfig
from spn_torchrl.envs import TASKS, task_spec
from spn_torchrl.envs.mujoco import MujocoBatchEnv, batch_task
from spn_torchrl.envs.mujoco_warp import MujocoWarpEnv, mujoco_warp_backend, torch_device
from spn_torchrl.evaluation import local_processes, machine_evaluator
from spn_torchrl.evaluation.processes import ProcessEvaluator
from spn_torchrl.evaluation.rollout import Episodes, Evaluator, PopulationEvaluator
from spn_torchrl.snn import neurons
from spn_torchrl.snn.policies import PopulationSPN, init_fixed_weights
from spn_torchrl.training import ga


def ceiling(env_id: str, population: int, threads: int, steps: int, repeats: int = 3) -> float:
    """Env steps/s of the physics alone: P simulations, frame_skip substeps per env step; the best of
    ``repeats`` runs from the same start (a ceiling is what the machine can do, not its average)."""
    task = batch_task(env_id)
    env = MujocoBatchEnv(env_id, 1)  # for its model, loaded exactly as the backend does
    rng = np.random.default_rng(0)
    low, high = env.model.actuator_ctrlrange.T
    controls = rng.uniform(low, high, size=(steps, population, env.model.nu))
    best = 0.0
    for _ in range(repeats):
        batch = Batch(env.model, population, nthread=threads)
        ctrl = batch.bind("ctrl")
        batch.step(nstep=task.frame_skip)
        t0 = time.perf_counter()
        for k in range(steps):
            ctrl[:] = controls[k]
            batch.step(nstep=task.frame_skip)
        best = max(best, population * steps / (time.perf_counter() - t0))
    return best


def task_config(env_id: str) -> DictConfig:
    """conf/env/<task>.yaml of a task id: how train.py runs it."""
    name = next(name for name, task_id in TASKS.items() if task_id == env_id)
    return OmegaConf.load(Path(__file__).resolve().parents[1] / "conf" / "env" / f"{name}.yaml")


def make_spn(env_id: str, seed: int = 0) -> PopulationSPN:
    spec = task_spec(env_id)
    gen = torch.Generator().manual_seed(seed)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, 64, gen)
    return PopulationSPN(w1, w2, action_low=spec.action_low, action_high=spec.action_high)


@dataclass
class Generation:
    steps_per_s: float
    steps: int
    physics_steps_per_s: float | None  # the physics alone of its episodes (mujoco_batch only)
    worker_memory_mb: float  # summed peak resident memory of its worker processes


def elite_slots(population: int) -> int:
    """Slots of the previous generation's re-evaluation beside N children: the top 10 (fewer for N < 100) x 10."""
    return min(10, population // 10) * 10


@dataclass
class Previous:
    """What the untimed previous generation leaves: its genomes, elite candidates and the children to evaluate."""

    population: int
    parents: torch.Tensor
    candidates: torch.Tensor
    children: torch.Tensor
    generator: torch.Generator


def previous_generation(evaluator: Evaluator, spn: PopulationSPN, population: int) -> Previous:
    """The untimed generation before the timed one, on ``evaluator`` (``population + elite_slots(population)``
    slots)."""
    gen = torch.Generator().manual_seed(0)
    parents = ga.initial_population(population, spn.genome_size, 0.01, gen)
    fitness = evaluator(parents, 1).returns
    candidates = ga.elite_candidates(fitness, elite_slots(population) // 10)
    children = ga.next_generation(parents, fitness, sigma=0.01, truncation=0.25, generator=gen)
    return Previous(population, parents, candidates, children, gen)


def timed_generation(evaluator: Evaluator, previous: Previous) -> tuple[Episodes, float]:
    """One GA generation of SPEC.md as spn_torchrl.training.evolve runs it in the steady state: one rollout of the
    N children and the previous generation's top 10 x 10 re-evaluation, elite pick, selection. Returns the
    rollout's episodes and the generation's seconds."""
    population, k, episodes = previous.population, elite_slots(previous.population) // 10, 10
    t0 = time.perf_counter()
    genomes = torch.cat([previous.children, ga.reevaluation_genomes(previous.parents, previous.candidates, episodes)])
    result = evaluator(genomes, 2)
    if k:  # no re-evaluation below N = 10
        ga.pick_elite(previous.candidates, result.part(population, population + k * episodes).returns.view(k, episodes))
    fitness = result.part(0, population).returns
    ga.elite_candidates(fitness, k)
    ga.next_generation(previous.children, fitness, sigma=0.01, truncation=0.25, generator=previous.generator)
    return result, time.perf_counter() - t0


def generation(
    env_id: str, backend: str, population: int, threads: int, episode_steps: int, processes: int = 1
) -> Generation:
    """:func:`timed_generation` on the evaluator that ``evaluator.processes=processes`` builds. The physics-alone
    rate divides its steps by the longest physics wall time of one shard (the shards' physics runs side by side)."""
    spn = make_spn(env_id)
    slots = population + elite_slots(population)
    evaluator = machine_evaluator(spn, env_id, slots, backend, threads, episode_steps, processes)
    try:
        previous = previous_generation(evaluator, spn, population)
        before = physics_seconds(evaluator)
        result, seconds = timed_generation(evaluator, previous)
        after = physics_seconds(evaluator)
        memory = sum(evaluator.gather("peak_memory_mb")) if isinstance(evaluator, ProcessEvaluator) else 0.0
    finally:
        evaluator.close()
    physics = None if after is None else result.total_steps / max(a - b for a, b in zip(after, before))
    return Generation(result.total_steps / seconds, result.total_steps, physics, memory)


PAPER_STEPS = 3e7  # env steps of one paper-budget seed (SPEC.md: G = 100 generations of A = 3e5)


@dataclass
class WarpGeneration:
    population: int
    slots: int
    steps_per_s: float  # one GA generation on the device
    physics_steps_per_s: float  # the captured substeps of every world alone
    memory_mb: float | None  # device memory: torch's peak allocation + Warp's pool's peak (None on cpu)
    build_s: float  # building the env (loading or compiling the kernels, capturing the graph)


def synchronize(env: MujocoWarpEnv) -> None:
    """Wait for the device's work (a no-op on cpu, where Warp and torch run synchronously)."""
    if env.device.type == "cuda":
        torch.cuda.synchronize(env.device)
        env._wp.synchronize_device(env.wp_device)


def physics_rate(env: MujocoWarpEnv, steps: int) -> float:
    """Env steps/s of :meth:`MujocoWarpEnv.simulate` alone over every world, with fixed random controls."""
    env.reset(seed=list(range(env.batch_size[0])))
    low, high = env.action_spec.space.low, env.action_spec.space.high
    gen = torch.Generator(device=env.device).manual_seed(0)
    env.ctrl.copy_(low + (high - low) * torch.rand(env.ctrl.shape, generator=gen, device=env.device))
    env.simulate()  # warm
    synchronize(env)
    t0 = time.perf_counter()
    for _ in range(steps):
        env.simulate()
    synchronize(env)
    return env.batch_size[0] * steps / (time.perf_counter() - t0)


def warp_generation(
    env_id: str, population: int, episode_steps: int, device: str, physics_steps: int
) -> WarpGeneration:
    """:func:`timed_generation` on a mujoco_warp env of N + elite_slots(N) worlds on ``device``, the device
    evaluator, then :func:`physics_rate` on the same worlds."""
    spn = make_spn(env_id)
    slots = population + elite_slots(population)
    cuda = device.startswith("cuda")
    if cuda:
        torch.cuda.reset_peak_memory_stats(device)
    t0 = time.perf_counter()
    env = mujoco_warp_backend(env_id, slots, device=device)
    build = time.perf_counter() - t0
    evaluator = PopulationEvaluator(env, spn, episode_steps)
    try:
        result, seconds = timed_generation(evaluator, previous_generation(evaluator, spn, population))
        physics = physics_rate(env, physics_steps)
        memory = None
        if cuda:
            wp = env._wp
            pool = wp.get_mempool_used_mem_high(env.wp_device) if wp.is_mempool_enabled(env.wp_device) else 0
            memory = (torch.cuda.max_memory_allocated(device) + pool) / 2**20
    finally:
        evaluator.close()
    return WarpGeneration(population, slots, result.total_steps / seconds, physics, memory, build)


def warp_table(env_id: str, populations: list[int], episode_steps: int, device: str, physics_steps: int) -> None:
    """Print the mujoco_warp figures of each population size as a markdown table."""
    device = str(torch_device(device))  # a clear error for a device this machine lacks
    print(f"mujoco_warp on {device}, {env_id}, {episode_steps}-step episodes (env steps/s)")
    print(
        "| N (slots) | GA generation | physics alone | generation / physics | device memory (MB) | "
        "paper-budget seed (3e7 steps) | env build (s) |"
    )
    print("|---|---|---|---|---|---|---|")
    for population in populations:
        g = warp_generation(env_id, population, episode_steps, device, physics_steps)
        memory = "n/a (cpu)" if g.memory_mb is None else f"{g.memory_mb:,.0f}"
        budget = PAPER_STEPS / g.steps_per_s
        print(
            f"| {g.population:,} ({g.slots:,}) | {g.steps_per_s:,.0f} | {g.physics_steps_per_s:,.0f} | "
            f"{g.steps_per_s / g.physics_steps_per_s:.3f} | {memory} | {budget / 60:,.1f} min | {g.build_s:.1f} |",
            flush=True,
        )
        gc.collect()  # free this size's worlds before the next one's


def physics_seconds(evaluator) -> list[float] | None:
    """Seconds each shard's env has spent in its physics call so far (None: not mujoco_batch)."""
    if isinstance(evaluator, ProcessEvaluator):
        seconds = evaluator.gather("physics_seconds")
    else:
        seconds = [getattr(evaluator.env, "physics_seconds", None)]
    return None if None in seconds else seconds


def paper_way(env_id: str, steps: int, mask_every_step: bool = True) -> float:
    """The authors' loop: one env, one single-genome SPN call per step that runs the LIF time steps one by
    one; their policy computed the sigmoid masks inside every call (SPEC.md), which ``mask_every_step``
    reproduces."""
    spn = make_spn(env_id)
    genome = torch.randn(1, spn.genome_size, generator=torch.Generator().manual_seed(0))
    spn.set_genomes(genome)
    env = gym.make(env_id)
    obs, _ = env.reset(seed=0)
    t0 = time.perf_counter()
    for _ in range(steps):
        with torch.no_grad():
            if mask_every_step:
                spn.set_genomes(genome)
            out, _ = neurons.spn_dynamics(spn.w1_eff, spn.w2_eff, torch.as_tensor(obs, dtype=torch.float32)[None])
            action = torch.clamp(out, spn.action_low, spn.action_high)
        obs, _, terminated, truncated, _ = env.step(action[0].numpy())
        if terminated or truncated:
            obs, _ = env.reset()
    seconds = time.perf_counter() - t0
    env.close()
    return steps / seconds


def peak_memory_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="HalfCheetah-v5")
    parser.add_argument(
        "--backend", default="mujoco_batch", choices=["mujoco_batch", "mujoco_warp"], help="the backend measured"
    )
    parser.add_argument("--device", default="cuda", help="mujoco_warp: cpu, cuda or cuda:<index>")
    parser.add_argument(
        "--populations", default="200,2000,20000", help="mujoco_warp: comma-separated population sizes N"
    )
    parser.add_argument("--physics-steps", type=int, default=100, help="mujoco_warp: env steps of the physics run")
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument(
        "--processes", type=int, help="evaluator processes (evaluator.processes; default: train.py's for the task)"
    )
    parser.add_argument(
        "--threads", type=int, help="physics threads per process (env.threads; default: the task config's)"
    )
    parser.add_argument("--paper-steps", type=int, default=3000, help="env steps of the paper-way slice")
    parser.add_argument("--ceiling-steps", type=int, default=300, help="batched env steps of the ceiling run")
    parser.add_argument("--episode-steps", type=int, default=1000, help="episode cut of the mujoco_batch generation")
    parser.add_argument(
        "--gym-episode-steps", type=int, default=1000, help="episode cut of the gymnasium generation (0: skip it)"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)
    if args.backend == "mujoco_warp":
        populations = [int(n) for n in args.populations.split(",")]
        warp_table(args.env, populations, args.episode_steps, args.device, args.physics_steps)
        return
    task = task_config(args.env)
    args.threads = args.threads or task.get("threads", 1)
    slots = args.population + 100
    args.processes = args.processes or local_processes(LocalEvaluatorConfig(), args.threads, slots)
    cores = args.processes * args.threads

    ceil = ceiling(args.env, args.population, cores, args.ceiling_steps)
    print(f"ceiling (mujoco.batch physics only, one batch on {cores} threads): {ceil:,.0f} env steps/s")
    batch = generation(args.env, "mujoco_batch", args.population, args.threads, args.episode_steps, args.processes)
    batch_sps, physics_sps = batch.steps_per_s, batch.physics_steps_per_s
    print(
        f"generation mujoco_batch ({args.processes} processes x {args.threads} physics threads): {batch.steps:,} steps, "
        f"{batch_sps:,.0f} env steps/s, {batch_sps / ceil:.3f} of ceiling"
    )
    print(
        f"  its physics alone (the SPN's controls): {physics_sps:,.0f} env steps/s, {physics_sps / ceil:.3f} of ceiling "
        f"(the bound on ratio_to_ceiling for any loop around this physics); the loop reaches {batch_sps / physics_sps:.3f} of it"
    )
    if args.gym_episode_steps:
        gym = generation(args.env, "gymnasium", args.population, 1, args.gym_episode_steps, args.processes)
        print(
            f"generation gymnasium (SyncVectorEnv, {args.processes} processes): {gym.steps:,} steps, "
            f"{gym.steps_per_s:,.0f} env steps/s, {gym.steps_per_s / ceil:.3f} of ceiling; "
            f"mujoco_batch is {batch_sps / gym.steps_per_s:.1f}x faster"
        )
    paper = paper_way(args.env, args.paper_steps)
    print(f"paper way (1 env, 1 policy call per step, masks computed in every call): {paper:,.0f} env steps/s")
    premasked = paper_way(args.env, args.paper_steps, mask_every_step=False)
    print(
        f"  the same with the masks computed once: {premasked:,.0f} env steps/s (mujoco_batch: {batch_sps / premasked:.1f}x)"
    )
    print(
        f"peak memory (maxrss): {peak_memory_mb() + batch.worker_memory_mb:,.0f} MB in all; this process "
        f"{peak_memory_mb():,.0f} MB, the mujoco_batch generation's worker processes {batch.worker_memory_mb:,.0f} MB "
        "together (each counts the shared libraries it maps)"
    )
    print(f"ratio_to_ceiling={batch_sps / ceil:.3f} speedup_vs_paper={batch_sps / paper:.1f}")


if __name__ == "__main__":
    main()
