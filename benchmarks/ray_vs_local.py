"""One GA generation (population and elite re-evaluation in one rollout) on the local evaluator and on Ray actors.

    python benchmarks/ray_vs_local.py --env halfcheetah --population 200 --actors 2 [--actor-workers 1]

Prints start-up and generation wall times of both, the overhead Ray adds, whether every episode is
identical, and the payload bytes the Ray evaluator moved.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import torch
from hydra import compose, initialize_config_dir

from spn_torchrl.config import register_configs, to_run_config
from spn_torchrl.envs import task_spec
from spn_torchrl.evaluation import make_evaluator
from spn_torchrl.evaluation.rollout import Episodes
from spn_torchrl.seeds import episode_seed
from spn_torchrl.snn.policies import init_fixed_weights, spn_from_config
from spn_torchrl.training import ga

CONF = str(Path(__file__).resolve().parents[1] / "conf")


def generation(
    evaluator, parents: torch.Tensor, k: int, episodes: int, seed: int, sigma: float
) -> tuple[float, Episodes]:
    """Wall time and episodes of one steady-state generation as spn_torchrl.training.evolve runs it: one call with
    the children and the parents' elite candidates (the parents' own rollout runs first, untimed)."""
    fitness = evaluator(parents, episode_seed(seed, 1, 0)).returns
    candidates = ga.elite_candidates(fitness, k)
    children = ga.next_generation(
        parents, fitness, sigma=sigma, truncation=0.25, generator=torch.Generator().manual_seed(seed)
    )
    genomes = torch.cat([children, ga.reevaluation_genomes(parents, candidates, episodes)])
    before = {key: getattr(evaluator, key, 0) for key in ("bytes_sent", "bytes_received")}
    t0 = time.perf_counter()
    result = evaluator(genomes, episode_seed(seed, 2, 0))
    seconds = time.perf_counter() - t0
    for key, value in before.items():
        if hasattr(evaluator, key):
            setattr(evaluator, key, getattr(evaluator, key) - value)
    return seconds, result


def measure(cfg, spec, spn, population) -> dict:
    t0 = time.perf_counter()
    evaluator = make_evaluator(cfg, spec, spn)
    startup = time.perf_counter() - t0
    try:
        seconds, episodes = generation(
            evaluator, population, cfg.algo.elite_candidates, cfg.algo.elite_episodes, cfg.seed, cfg.algo.sigma
        )
    finally:
        evaluator.close()
    return {
        "startup_s": round(startup, 2),
        "generation_s": round(seconds, 2),
        "env_steps": episodes.total_steps,
        "steps_per_s": round(episodes.total_steps / seconds),
        "bytes_setup": getattr(evaluator, "bytes_setup", 0),
        "bytes_sent": getattr(evaluator, "bytes_sent", 0),
        "bytes_received": getattr(evaluator, "bytes_received", 0),
        "episodes": episodes,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="halfcheetah")
    parser.add_argument("--algo", default="conn_ga")
    parser.add_argument("--population", type=int, default=200)
    parser.add_argument("--actors", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--actor-threads", type=int, default=None, help="env.threads of each Ray actor (default: the env config's)"
    )
    args = parser.parse_args()

    register_configs()
    overrides = [f"env={args.env}", f"algo={args.algo}", f"algo.population={args.population}", f"seed={args.seed}"]
    with initialize_config_dir(config_dir=CONF, version_base=None):
        local_cfg = to_run_config(compose(config_name="config", overrides=overrides))
        ray_cfg = compose(
            config_name="config",
            overrides=[
                *overrides,
                "evaluator=ray",
                f"evaluator.num_actors={args.actors}",
                f"evaluator.num_cpus={args.actors}",
                *([f"env.threads={args.actor_threads}"] if args.actor_threads else []),
            ],
        )
    ray_cfg = to_run_config(ray_cfg)
    torch.set_num_threads(1)
    spec = task_spec(local_cfg.env.id)
    generator = torch.Generator().manual_seed(args.seed)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, local_cfg.algo.snn.hidden, generator)
    spn = spn_from_config(local_cfg.algo.snn, local_cfg.algo.genome, spec, w1, w2)
    population = ga.initial_population(args.population, spn.genome_size, local_cfg.algo.sigma, generator)

    local = measure(local_cfg, spec, spn, population)
    remote = measure(ray_cfg, spec, spn, population)
    a, b = local.pop("episodes"), remote.pop("episodes")
    identical = all(torch.equal(getattr(a, f), getattr(b, f)) for f in ("returns", "steps", "spikes"))
    report = {
        "env": spec.env_id,
        "algo": args.algo,
        "population": args.population,
        "genome_size": spn.genome_size,
        "actors": args.actors,
        "local": local,
        "ray": remote,
        "ray_overhead_s": round(remote["generation_s"] - local["generation_s"], 2),
        "identical_episodes": identical,
        "float32_genome_bytes_per_generation": 4
        * spn.genome_size
        * (args.population + ray_cfg.algo.elite_candidates * ray_cfg.algo.elite_episodes),
    }
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()
