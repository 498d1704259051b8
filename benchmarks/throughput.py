"""Env steps/s of a GA generation against the physics ceiling and the paper's serial loop.

    python benchmarks/throughput.py --env HalfCheetah-v5 --population 200 --threads 2

Measures in one process: (a) the ceiling, batched physics only (mujoco.batch, random controls);
(b) one GA generation per backend as spn_torchrl.evolve runs it (the population and the previous
generation's elite re-evaluation in one rollout, then selection) through PopulationEvaluator and ga;
(c) the paper's way, one Gymnasium env and one single-policy SPN call per step that computes the masks (as
the authors' code did), on a short slice, and the same loop with masks computed once. The last line is
``ratio_to_ceiling=<x> speedup_vs_paper=<y>``.
"""

from __future__ import annotations

import argparse
import resource
import time

import gymnasium as gym
import numpy as np
import torch
from mujoco.batch import Batch

from spn_torchrl import ga
from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.evaluate import PopulationEvaluator
from spn_torchrl.mujoco_batch import MujocoBatchEnv, batch_task
from spn_torchrl.policies import PopulationSPN, init_fixed_weights


def ceiling(env_id: str, population: int, threads: int, steps: int) -> float:
    """Env steps/s of the physics alone: P simulations, frame_skip substeps per env step."""
    task = batch_task(env_id)
    env = MujocoBatchEnv(env_id, 1)  # for its model, loaded exactly as the backend does
    batch = Batch(env.model, population, nthread=threads)
    ctrl = batch.bind("ctrl")
    rng = np.random.default_rng(0)
    low, high = env.model.actuator_ctrlrange.T
    controls = rng.uniform(low, high, size=(steps, population, env.model.nu))
    batch.step(nstep=task.frame_skip)
    t0 = time.perf_counter()
    for k in range(steps):
        ctrl[:] = controls[k]
        batch.step(nstep=task.frame_skip)
    return population * steps / (time.perf_counter() - t0)


def make_spn(env_id: str, seed: int = 0) -> PopulationSPN:
    spec = task_spec(env_id)
    gen = torch.Generator().manual_seed(seed)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, 64, gen)
    return PopulationSPN(w1, w2, action_low=spec.action_low, action_high=spec.action_high)


def generation(
    env_id: str, backend: str, population: int, threads: int, episode_steps: int
) -> tuple[float, int, float | None]:
    """One GA generation of SPEC.md as spn_torchrl.evolve runs it in the steady state: one rollout of the N
    children and the previous generation's top 10 x 10 re-evaluation, elite pick, selection. Returns
    steps/s, steps and, for mujoco_batch, the share of its wall time spent inside the physics call."""
    spn = make_spn(env_id)
    gen = torch.Generator().manual_seed(0)
    parents = ga.initial_population(population, spn.genome_size, 0.01, gen)
    k, episodes = min(10, population // 10), 10
    env = make_batched_env(env_id, population + k * episodes, backend=backend, num_workers=threads)
    evaluator = PopulationEvaluator(env, spn, episode_steps)
    try:
        fitness = evaluator(parents, seed=1).returns  # the previous generation, not timed
        candidates = ga.elite_candidates(fitness, k)
        children = ga.next_generation(parents, fitness, sigma=0.01, truncation=0.25, generator=gen)
        if hasattr(env, "physics_seconds"):
            env.physics_seconds = 0.0
        t0 = time.perf_counter()
        result = evaluator(torch.cat([children, ga.reevaluation_genomes(parents, candidates, episodes)]), seed=2)
        ga.pick_elite(candidates, result.part(population, population + k * episodes).returns.view(k, episodes))
        fitness = result.part(0, population).returns
        ga.elite_candidates(fitness, k)
        ga.next_generation(children, fitness, sigma=0.01, truncation=0.25, generator=gen)
        seconds = time.perf_counter() - t0
    finally:
        evaluator.close()
    physics = getattr(env, "physics_seconds", None)
    return result.total_steps / seconds, result.total_steps, None if physics is None else physics / seconds


def paper_way(env_id: str, steps: int, mask_every_step: bool = True) -> float:
    """The authors' loop: one env, one single-genome SPN call per step; their policy computed the
    sigmoid masks inside every call (SPEC.md), which ``mask_every_step`` reproduces."""
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
            action, _ = spn(torch.as_tensor(obs, dtype=torch.float32)[None])
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
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--threads", type=int, default=2, help="physics threads (torch stays at 1)")
    parser.add_argument("--paper-steps", type=int, default=3000, help="env steps of the paper-way slice")
    parser.add_argument("--ceiling-steps", type=int, default=300, help="batched env steps of the ceiling run")
    parser.add_argument("--episode-steps", type=int, default=1000, help="episode cut of the mujoco_batch generation")
    parser.add_argument(
        "--gym-episode-steps", type=int, default=1000, help="episode cut of the gymnasium generation (0: skip it)"
    )
    args = parser.parse_args()
    torch.set_num_threads(1)

    ceil = ceiling(args.env, args.population, args.threads, args.ceiling_steps)
    print(f"ceiling (mujoco.batch physics only, {args.threads} threads): {ceil:,.0f} env steps/s")
    batch_sps, batch_steps, share = generation(args.env, "mujoco_batch", args.population, args.threads, args.episode_steps)
    print(f"generation mujoco_batch: {batch_steps:,} steps, {batch_sps:,.0f} env steps/s, {batch_sps / ceil:.3f} of ceiling")
    physics_sps = batch_sps / share
    print(f"  share of its wall time inside the physics call: {share:.3f}")
    print(
        f"  its physics alone (the SPN's controls): {physics_sps:,.0f} env steps/s, {physics_sps / ceil:.3f} of ceiling "
        "(the bound on ratio_to_ceiling for any loop around this physics)"
    )
    if args.gym_episode_steps:
        gym_sps, gym_steps, _ = generation(args.env, "gymnasium", args.population, 1, args.gym_episode_steps)
        print(
            f"generation gymnasium (SyncVectorEnv): {gym_steps:,} steps, {gym_sps:,.0f} env steps/s, "
            f"{gym_sps / ceil:.3f} of ceiling; mujoco_batch is {batch_sps / gym_sps:.1f}x faster"
        )
    paper = paper_way(args.env, args.paper_steps)
    print(f"paper way (1 env, 1 policy call per step, masks computed in every call): {paper:,.0f} env steps/s")
    premasked = paper_way(args.env, args.paper_steps, mask_every_step=False)
    print(f"  the same with the masks computed once: {premasked:,.0f} env steps/s (mujoco_batch: {batch_sps / premasked:.1f}x)")
    print(f"peak memory (maxrss): {peak_memory_mb():,.0f} MB")
    print(f"ratio_to_ceiling={batch_sps / ceil:.3f} speedup_vs_paper={batch_sps / paper:.1f}")


if __name__ == "__main__":
    main()
