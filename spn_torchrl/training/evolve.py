"""A GA run: build the env and SPN once, then evaluate, re-evaluate the elite, select, log, checkpoint."""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from omegaconf import DictConfig, OmegaConf

from spn_torchrl import checkpoint
from spn_torchrl.envs import task_spec
from spn_torchrl.errors import ConfigError
from spn_torchrl.evaluation import make_evaluator
from spn_torchrl.evaluation.rollout import Episodes, spike_rate
from spn_torchrl.records import Progress, close_logger, logger_run_id, make_logger
from spn_torchrl.seeds import FITNESS, REEVALUATION, episode_seeds
from spn_torchrl.snn.policies import genome_size, init_fixed_weights, mask_density, spn_from_config
from spn_torchrl.training import ga

log = logging.getLogger("spn_torchrl")


def run_meta(cfg: DictConfig, spec) -> dict[str, Any]:
    """What a checkpoint must match to be resumed by this config."""
    return {
        "format": checkpoint.GA_FORMAT,
        "env_id": spec.env_id,
        "genome": cfg.algo.genome,
        "n_obs": spec.n_obs,
        "n_act": spec.n_act,
        "hidden": cfg.algo.hidden,
        "population": cfg.algo.population,
    }


def evolve(cfg: DictConfig, run_dir: Path, run_name: str) -> dict[str, Any]:
    """Run (or resume) the GA of SPEC.md; returns the last generation's metrics.

    The elite re-evaluation of generation g does not change selection (SPEC.md), so it runs in the same
    batched rollout as the population of generation g+1 (one env of N + k x episodes slots), and the last
    generation's in a rollout of its own. Generation g's row is written once its re-evaluation is done.
    Each episode's env seed derives from (run seed, generation, role, index) (:mod:`spn_torchrl.seeds`), so
    the rows do not depend on how a generation's episodes are split into rollouts, processes or actors.
    """
    algo = cfg.algo
    spec = task_spec(cfg.env.id)
    meta = run_meta(cfg, spec)
    ckpt_path = run_dir / checkpoint.CHECKPOINT_NAME
    generator = torch.Generator()

    if ckpt_path.exists() and not cfg.resume:
        raise ConfigError(f"{run_dir} already holds a run: pass resume=true to continue it, or use a new run directory")
    if cfg.resume and ckpt_path.exists():
        state = checkpoint.load(ckpt_path, expected=meta)
        w1, w2 = state["w1"], state["w2"]
        generator.set_state(state["rng"])
        population, start = state["population"], state["generation"]
        elites, total_steps, wall = list(state["elites"]), state["total_env_steps"], state["wall_time_s"]
        run_name, wandb_id, pending = state["run_name"], state["wandb_id"], state["pending"]
        log.info("resuming %s after generation %d", run_dir, start)
    else:
        if cfg.resume:
            log.info("resume=true but %s holds no checkpoint: starting a new run", run_dir)
        generator.manual_seed(cfg.seed)
        w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, algo.hidden, generator)
        dim = genome_size(w1, w2)
        center = torch.cat([w1.flatten(), w2.flatten()]) if algo.init_from_fixed_weights else None
        population = ga.initial_population(algo.population, dim, algo.sigma, generator, center)
        start, elites, total_steps, wall, wandb_id, pending = 0, [], 0, 0.0, None, None

    spn = spn_from_config(cfg.algo, spec, w1, w2)
    progress = Progress(run_dir / "progress.csv", keep_rows=len(elites))
    evaluator = make_evaluator(cfg, spec, spn)
    logger = None
    k, episodes, n = algo.elite_candidates, algo.elite_episodes, algo.population
    row: dict[str, Any] = {}
    failed = True
    started = time.perf_counter()
    since_row = {"steps": 0, "wall": wall}  # env steps run and wall time at the previous row

    def elapsed() -> float:
        """Wall time of the run so far, earlier segments of a resumed run included."""
        return wall + time.perf_counter() - started

    def finish(pending: dict[str, Any], reeval: Episodes) -> None:
        """Pick the elite of a pending generation from its re-evaluation; write its row."""
        nonlocal total_steps, row
        now = elapsed()
        candidates, fitness = pending["candidates"], pending["fitness"]
        elite_index, elite_return = ga.pick_elite(candidates, reeval.returns.view(k, episodes))
        elite = pending["population"][elite_index]
        elites.append(elite.clone())
        slot = int((candidates == elite_index).nonzero()[0]) * episodes
        mask1, mask2 = spn.masks(elite[None])
        steps = pending["steps"] + reeval.total_steps
        total_steps += steps
        generation = pending["generation"]
        row = {
            "generation": generation,
            "eval_return": elite_return,
            "best_fitness": float(fitness.max()),
            "mean_fitness": float(fitness.mean()),
            "env_steps": steps,
            "total_env_steps": total_steps,
            "wall_time_s": round(now, 3),
            "steps_per_s": round(since_row["steps"] / max(now - since_row["wall"], 1e-9), 1),
            "mask_density": mask_density(mask1, mask2),
            "spike_rate": spike_rate(
                reeval.spikes[slot : slot + episodes],
                reeval.steps[slot : slot + episodes],
                algo.hidden,
                algo.time_steps,
            ),
            "synapses_l1": int(mask1.sum()),
            "synapses_l2": int(mask2.sum()),
            "elite_index": elite_index,
        }
        since_row.update(steps=0, wall=now)
        progress.append(row)
        if logger is not None:
            logger.log_metrics({f"train/{key}": value for key, value in row.items()}, step=generation)
        log.info(
            "gen %d/%d  eval_return %.2f  best %.2f  mean %.2f  steps %d  %.0f steps/s  density %.3f  spike_rate %.3f",
            generation,
            algo.generations,
            elite_return,
            row["best_fitness"],
            row["mean_fitness"],
            total_steps,
            row["steps_per_s"],
            row["mask_density"],
            row["spike_rate"],
        )

    def save(generation: int) -> None:
        checkpoint.save(
            {
                "meta": meta,
                "config": OmegaConf.to_yaml(cfg, resolve=True),
                "run_name": run_name,
                "wandb_id": wandb_id,
                "generation": generation,
                "population": population,
                "pending": pending,
                "rng": generator.get_state(),
                "w1": w1,
                "w2": w2,
                "elites": torch.stack(elites) if elites else torch.empty(0, genome_size(w1, w2)),
                "total_env_steps": total_steps,
                "wall_time_s": elapsed(),
            },
            run_dir,
        )

    def rollout(genomes: torch.Tensor, seeds: np.ndarray) -> Episodes:
        result = evaluator(genomes, seeds)
        since_row["steps"] += result.total_steps
        return result

    try:
        logger = make_logger(cfg, run_dir, run_name, wandb_id)
        log.info("run %s in %s", run_name, run_dir)
        wandb_id = logger_run_id(logger)
        for generation in range(start + 1, algo.generations + 1):
            genomes, seeds = [population], [episode_seeds(cfg.seed, generation, FITNESS, n)]
            if pending is not None:
                genomes.append(ga.reevaluation_genomes(pending["population"], pending["candidates"], episodes))
                seeds.append(episode_seeds(cfg.seed, pending["generation"], REEVALUATION, k * episodes))
            result = rollout(torch.cat(genomes), np.concatenate(seeds))
            fitness_eps = result.part(0, n)
            if pending is not None:
                finish(pending, result.part(n, result.returns.numel()))
            fitness = fitness_eps.returns
            pending = {
                "generation": generation,
                "population": population,
                "fitness": fitness,
                "steps": fitness_eps.total_steps,
                "candidates": ga.elite_candidates(fitness, k),
            }
            population = ga.next_generation(
                population,
                fitness,
                sigma=algo.sigma,
                truncation=algo.truncation,
                generator=generator,
                elitism=algo.elitism,
            )
            save(generation)
        if pending is not None:  # the last generation's re-evaluation, alone
            genomes = ga.reevaluation_genomes(pending["population"], pending["candidates"], episodes)
            finish(
                pending, rollout(genomes, episode_seeds(cfg.seed, pending["generation"], REEVALUATION, k * episodes))
            )
            pending = None
            save(algo.generations)
        failed = False
    finally:
        try:
            evaluator.close()
        finally:
            close_logger(logger, failed)
    return row
