"""Env steps/s of one Connections-GA generation here against EvoTorch doing the same job (this file is not named
evotorch.py: beside it, `import evotorch` would find itself).

    pip install --no-deps evotorch==0.6.1 cma pandas    # the bench extra; torch, numpy, gymnasium, ray as here
    python benchmarks/against_evotorch.py [--population 200 --episode-steps 1000 --gymne-episode-steps 100 --actors 1,2]

Ours: benchmarks/throughput.py's steady-state GA generation (N children and the previous generation's 10 x 10 elite
re-evaluation in one rollout, then selection) on the default evaluator (mujoco_batch, 2 processes x 1 thread) and on
env.backend=gymnasium (SyncVectorEnv, 2 processes).
EvoTorch: ``GeneticAlgorithm`` (elitist, Gaussian mutation stdev 0.01, its default ``re_evaluate=True``: the N parents
and N children in one evaluation) on ``VecGymNE`` (one SyncVectorEnv of gymnasium envs per actor, the policy
vmapped over the solutions) and on ``GymNE`` (one env per actor, one policy call per solution and step), each with
``num_actors`` Ray actors.
Both sides run the same SPN: EvoTorch evolves ``TrainableSPN``'s connection scores (the genome, its only parameter;
the fixed weights are buffers), with the Heaviside spike written without ``out=`` so that vmap accepts it.
An untimed warm-up builds every env and actor the timed generation uses. GymNE's default episodes are short
(``--gymne-episode-steps 100``) because one 2N x 1000-step generation takes minutes; HalfCheetah never terminates,
so the episode cut barely moves its rate. The last line is ``ratio_vs_vecgymne=<x> ratio_vs_gymne=<y>``.
"""

from __future__ import annotations

import argparse
import time

import torch
from throughput import generation, make_spn, task_config  # benchmarks/throughput.py, beside this script

from spn_torchrl.config import LocalEvaluatorConfig
from spn_torchrl.evaluation import local_processes
from spn_torchrl.snn.policies import TrainableSPN


def heaviside(v: torch.Tensor, v_th: float) -> torch.Tensor:
    """neurons.heaviside's values without its ``out=`` (which vmap cannot batch)."""
    return (v > v_th).to(v.dtype)


def evotorch_generation(problem_kind: str, env_id: str, population: int, episode_steps: int, actors: int) -> float:
    """Env steps/s of one EvoTorch GeneticAlgorithm step (2N episodes) on GymNE or VecGymNE with ``actors`` Ray
    actors (0: in this process), after an untimed warm-up evaluation."""
    from evotorch.algorithms import GeneticAlgorithm
    from evotorch.neuroevolution import GymNE, VecGymNE
    from evotorch.operators import GaussianMutation

    spn = make_spn(env_id)
    net = TrainableSPN(spn, torch.zeros(spn.genome_size), heaviside)
    if problem_kind == "vecgymne":
        problem = VecGymNE(env_id, net, env_config={"max_episode_steps": episode_steps}, num_actors=actors or None)
        warm = 2 * population  # VecGymNE rebuilds its vector env when a batch outgrows it
    else:
        problem = GymNE(
            env_id, net, episode_length=episode_steps, num_actors=actors or None, initial_bounds=(-0.01, 0.01)
        )
        warm = max(actors, 1)  # one env per actor, kept
    searcher = GeneticAlgorithm(problem, popsize=population, operators=[GaussianMutation(problem, stdev=0.01)])
    problem.evaluate(problem.generate_batch(warm))
    before = problem.interaction_count
    t0 = time.perf_counter()
    searcher.step()
    seconds = time.perf_counter() - t0
    steps = problem.interaction_count - before
    if problem.actors:  # num_actors=1 may run in this process (no actor to stop)
        problem.kill_actors()
    return steps / seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--env", default="HalfCheetah-v5")
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--episode-steps", type=int, default=1000, help="episode cut of ours and VecGymNE's")
    parser.add_argument("--gymne-episode-steps", type=int, default=100, help="episode cut of GymNE's (0: skip it)")
    parser.add_argument("--actors", default="1,2", help="comma-separated EvoTorch num_actors (0: no Ray)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    threads = task_config(args.env).get("threads", 1)
    processes = local_processes(LocalEvaluatorConfig(), threads, args.population + 100)
    ours = generation(args.env, "mujoco_batch", args.population, threads, args.episode_steps, processes)
    print(f"ours, mujoco_batch ({processes} processes x {threads} thread): {ours.steps_per_s:,.0f} env steps/s")
    gym = generation(args.env, "gymnasium", args.population, 1, args.episode_steps, processes)
    print(f"ours, gymnasium SyncVectorEnv ({processes} processes): {gym.steps_per_s:,.0f} env steps/s")
    best = {}
    for actors in (int(a) for a in args.actors.split(",")):
        for kind, steps in (("vecgymne", args.episode_steps), ("gymne", args.gymne_episode_steps)):
            if not steps:
                continue
            rate = evotorch_generation(kind, args.env, args.population, steps, actors)
            best[kind] = max(best.get(kind, 0.0), rate)
            print(
                f"EvoTorch GeneticAlgorithm on {kind} (num_actors={actors}, {steps}-step episodes): "
                f"{rate:,.0f} env steps/s; ours mujoco_batch is {ours.steps_per_s / rate:.1f}x, "
                f"ours gymnasium {gym.steps_per_s / rate:.1f}x",
                flush=True,
            )
    ratios = " ".join(f"ratio_vs_{kind}={ours.steps_per_s / rate:.1f}" for kind, rate in best.items())
    print(ratios)


if __name__ == "__main__":
    main()
