"""A GA or EC run: build the env and SPN once, then evaluate, re-evaluate the elite, step, record, checkpoint.

The two methods share this loop; they differ in their elite candidates and their step from one generation to the
next (:class:`~spn_torchrl.training.ga.GAStep`, :class:`~spn_torchrl.training.ec.ECStep`)."""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from spn_torchrl import checkpoint
from spn_torchrl.config import ECConfig, GAConfig, RunConfig
from spn_torchrl.envs import TaskSpec, task_spec
from spn_torchrl.evaluation import make_evaluator
from spn_torchrl.evaluation.rollout import Episodes, spike_rate
from spn_torchrl.lifecycle import Run, open_run
from spn_torchrl.seeds import FITNESS, REEVALUATION, episode_seeds
from spn_torchrl.snn import observations
from spn_torchrl.snn.policies import genome_size, init_fixed_weights, mask_density, spn_from_config
from spn_torchrl.training import ec, ga

log = logging.getLogger("spn_torchrl")


def run_meta(cfg: RunConfig, spec: TaskSpec) -> dict[str, Any]:
    """What a checkpoint must match to be resumed by this config (beyond the config contract): the format, the
    task and the network's shape."""
    return {
        "format": checkpoint.EC_FORMAT if isinstance(cfg.algo, ECConfig) else checkpoint.GA_FORMAT,
        "env_id": spec.env_id,
        "genome": cfg.algo.genome,
        "n_obs": spec.n_obs,
        "n_act": spec.n_act,
        "hidden": cfg.algo.snn.hidden,
    }


def initial_state(algo: GAConfig | ECConfig, spec: TaskSpec, seed: int, normalize: bool = False) -> dict[str, Any]:
    """Generation 0 of a new run: the fixed weights and the first population (EC: and p, Adam's state), drawn from
    the run seed; a GA and an EC run of one seed share their fixed weights. ``normalize``: and the observation
    statistics before any observation."""
    generator = torch.Generator().manual_seed(seed)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, algo.snn.hidden, generator)
    if isinstance(algo, ECConfig):
        method = ec.initial_state(algo, genome_size(w1, w2), generator)
    else:
        center = torch.cat([w1.flatten(), w2.flatten()]) if algo.init_from_fixed_weights else None
        population = ga.initial_population(algo.population, genome_size(w1, w2), algo.sigma, generator, center)
        method = {"population": population}
    if normalize:  # each elite's normalisation beside it; the running statistics
        method.update(elite_norms=torch.empty(2, 0, spec.n_obs), obs_stats=observations.initial_stats(spec.n_obs))
    return {
        **method,
        "generation": 0,
        "pending": None,
        "rng": generator.get_state(),
        "w1": w1,
        "w2": w2,
        "elites": torch.empty(0, genome_size(w1, w2)),
        "total_env_steps": 0,
        "wall_time_s": 0.0,
    }


def evolve(cfg: RunConfig, run_dir: Path, run_name: str) -> dict[str, Any]:
    """Run (or resume) the GA of SPEC.md or EC (``algo=conn_ec``); returns the last generation's metrics.

    The elite re-evaluation of generation g does not change selection (SPEC.md), so it runs in the same
    batched rollout as the population of generation g+1 (one env of N + k x episodes slots), and the last
    generation's in a rollout of its own. Generation g's row is written once its re-evaluation is done.
    With ``normalize_observations`` a generation's population sees the running statistics as they stood
    before it, which are then updated from every observation its fitness episodes fed a policy (EC:
    ``ec.py`` l. 125, 263); its elite is re-evaluated with the same statistics as its population, as EC's
    deterministic mask is (l. 209-214), and the checkpoint keeps them beside each elite (``elite_norms``)
    for ``play`` and ``export``.
    Each episode's env seed derives from (run seed, generation, role, index) (:mod:`spn_torchrl.seeds`), so
    the rows do not depend on how a generation's episodes are split into rollouts, processes or actors, and a
    run extended to more generations writes the rows of an uninterrupted longer run.
    """
    spec = task_spec(cfg.env.id)
    with open_run(cfg, run_dir, run_name, cfg.algo.kind, run_meta(cfg, spec), cfg.algo.generations) as run:
        state = run.state or initial_state(cfg.algo, spec, cfg.seed, cfg.normalize_observations)
        done = state["generation"]  # at most algo.generations: open_run refuses a smaller budget
        if done == cfg.algo.generations and state["pending"] is None:
            log.info("%s already ran its %d generations", run_dir, done)
            return run.rows[-1] if run.rows else {}
        if run.state is not None:
            waiting = "" if state["pending"] is None else "; its row follows its elite's re-evaluation"
            log.info("resuming %s after generation %d%s", run_dir, done, waiting)
        return _generations(cfg, spec, run, state)


def _generations(cfg: RunConfig, spec: TaskSpec, run: Run, state: dict[str, Any]) -> dict[str, Any]:
    """The loop from ``state`` to ``algo.generations``, recording each generation's row and checkpoint."""
    algo = cfg.algo
    method = ec.ECStep(algo, state) if isinstance(algo, ECConfig) else ga.GAStep(algo, state)
    generator = torch.Generator()
    generator.set_state(state["rng"])
    w1, w2 = state["w1"], state["w2"]
    population, start, pending = state["population"], state["generation"], state["pending"]
    elites, total_steps, wall = list(state["elites"]), state["total_env_steps"], state["wall_time_s"]
    stats = state.get("obs_stats")  # None: raw observations (the paper's)
    elite_norms = [] if stats is None else list(zip(*state["elite_norms"]))
    spn = spn_from_config(algo.snn, algo.genome, spec, w1, w2)
    k, episodes, n = algo.elite_candidates, algo.elite_episodes, algo.population
    row: dict[str, Any] = {}
    started = time.perf_counter()
    since_row = {"steps": 0, "wall": wall}  # env steps run and wall time at the previous row

    def elapsed() -> float:
        """Wall time of the run so far, earlier segments of a resumed run included."""
        return wall + time.perf_counter() - started

    def finish(pending: dict[str, Any], reeval: Episodes) -> None:
        """Pick the elite of a pending generation from its re-evaluation; record its row."""
        nonlocal total_steps, row
        now = elapsed()
        candidates, fitness = pending["candidates"], pending["fitness"]
        elite_index, elite_return = ga.pick_elite(candidates, reeval.returns.view(k, episodes))
        elite = pending["population"][elite_index]
        elites.append(elite.clone())
        if stats is not None:
            elite_norms.append(pending["obs_norm"])
        slot = int((candidates == elite_index).nonzero()[0]) * episodes
        mask1, mask2 = spn.masks(elite[None])
        steps = pending["steps"] + reeval.total_steps
        total_steps += steps
        generation = pending["generation"]
        rate = spike_rate(
            reeval.spikes[slot : slot + episodes],
            reeval.steps[slot : slot + episodes],
            algo.snn.hidden,
            algo.snn.time_steps,
        )
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
            "spike_rate": rate,
            "synapses_l1": int(mask1.sum()),
            "synapses_l2": int(mask2.sum()),
            "elite_index": elite_index if method.elite_from_population else -1,
        }
        since_row.update(steps=0, wall=now)
        run.record(row, step=generation)
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
        run.save(
            {
                "generation": generation,
                "population": population,
                "pending": pending,
                "rng": generator.get_state(),
                "w1": w1,
                "w2": w2,
                "elites": torch.stack(elites) if elites else torch.empty(0, genome_size(w1, w2)),
                "total_env_steps": total_steps,
                "wall_time_s": elapsed(),
                **method.state(),
                **({} if stats is None else {"obs_stats": stats, "elite_norms": stacked_norms()}),
            }
        )

    def stacked_norms() -> torch.Tensor:
        """Each elite's (mean, inv_std), [2, G, n]."""
        if not elite_norms:
            return torch.empty(2, 0, spec.n_obs)
        return torch.stack([torch.stack(list(part)) for part in zip(*elite_norms)])

    def rollout(genomes: torch.Tensor, seeds: np.ndarray, norm: observations.Norm | None, generation: int) -> Episodes:
        at = f"generation {generation}"
        if isinstance(algo, GAConfig):  # EC's genomes are masks written as +-inf (ec.mask_genomes)
            run.require_finite(f"a genome of the population (algo.sigma={algo.sigma:g})", genomes, at)
        result = evaluator(genomes, seeds) if norm is None else evaluator(genomes, seeds, norm)
        run.require_finite("an episode return", result.returns, at)
        since_row["steps"] += result.total_steps
        return result

    def slots_norm(norm: observations.Norm | None, count: int) -> observations.Norm | None:
        """``norm`` for ``count`` slots ([count, n] each), or None."""
        return None if norm is None else (norm[0].expand(count, -1), norm[1].expand(count, -1))

    def joined(norms: list[observations.Norm | None]) -> observations.Norm | None:
        """The slots' norms of one rollout's parts, in slot order (None: raw observations)."""
        return None if norms[0] is None else (torch.cat([m for m, _ in norms]), torch.cat([s for _, s in norms]))

    def reevaluation(pending: dict[str, Any]) -> tuple[torch.Tensor, np.ndarray, observations.Norm | None]:
        genomes = ga.reevaluation_genomes(pending["population"], pending["candidates"], episodes)
        seeds = episode_seeds(cfg.seed, pending["generation"], REEVALUATION, k * episodes)
        return genomes, seeds, slots_norm(pending.get("obs_norm"), k * episodes)

    evaluator = make_evaluator(cfg, spec, spn)
    try:
        for generation in range(start + 1, algo.generations + 1):
            norm = None if stats is None else observations.policy_norm(stats)
            genomes, seeds, norms = (
                [population],
                [episode_seeds(cfg.seed, generation, FITNESS, n)],
                [slots_norm(norm, n)],
            )
            if pending is not None:
                for part, into in zip(reevaluation(pending), (genomes, seeds, norms)):
                    into.append(part)
            result = rollout(torch.cat(genomes), np.concatenate(seeds), joined(norms), generation)
            fitness_eps = result.part(0, n)
            if pending is not None:
                finish(pending, result.part(n, result.returns.numel()))
            if stats is not None:
                stats = observations.update(stats, observations.slot_moments(*fitness_eps.moments))
            fitness = fitness_eps.returns
            pool, candidates = method.elite_pool(population, fitness)
            pending = {
                "generation": generation,
                "population": pool,
                "fitness": fitness,
                "steps": fitness_eps.total_steps,
                "candidates": candidates,
                **({} if norm is None else {"obs_norm": norm}),
            }
            population = method.advance(population, fitness, generator)
            save(generation)
        if pending is not None:  # the last generation's re-evaluation, alone
            finish(pending, rollout(*reevaluation(pending), pending["generation"]))
            pending = None
            save(algo.generations)
    finally:
        evaluator.close()
    return row
