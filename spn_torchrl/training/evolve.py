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


def start_state(cfg: RunConfig, spec: TaskSpec, run: Run) -> dict[str, Any] | None:
    """The state an open run goes on from (a new run's generation 0), or None when it has run its generations
    (``open_run`` refuses a budget below what it has done)."""
    state = run.state or initial_state(cfg.algo, spec, cfg.seed, cfg.normalize_observations)
    done = state["generation"]
    if done == cfg.algo.generations and state["pending"] is None:
        log.info("%s already ran its %d generations", run.dir, done)
        return None
    if run.state is not None:
        waiting = "" if state["pending"] is None else "; its row follows its elite's re-evaluation"
        log.info("resuming %s after generation %d%s", run.dir, done, waiting)
    return state


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
    with open_run(cfg, run_dir, run_name, cfg.algo.kind, run_meta(cfg, spec)) as run:
        state = start_state(cfg, spec, run)
        if state is None:
            return run.rows[-1] if run.rows else {}
        loop = Generations(cfg, spec, run, state)
        evaluator = make_evaluator(cfg, spec, loop.spn)
        try:
            while (request := loop.next_rollout()) is not None:
                genomes, seeds, norm = request
                loop.take(evaluator(genomes, seeds) if norm is None else evaluator(genomes, seeds, norm))
        finally:
            evaluator.close()
        return loop.row


Rollout = tuple[torch.Tensor, np.ndarray, observations.Norm | None]  # genomes [B, D], env seeds [B], slots' norm


class Generations:
    """One GA or EC run's loop from ``state`` to ``algo.generations``, a rollout at a time: :meth:`next_rollout`
    gives the genomes, env seeds and observation normalisation of its next rollout (None: done), :meth:`take` its
    episodes: a generation's step and checkpoint, and the previous generation's row once its elite is
    re-evaluated. Several runs in lockstep (:mod:`spn_torchrl.training.lockstep`) share each rollout."""

    def __init__(self, cfg: RunConfig, spec: TaskSpec, run: Run, state: dict[str, Any], label: str = "") -> None:
        self.cfg, self.spec, self.run, self.label = cfg, spec, run, label
        algo = cfg.algo
        self.method = ec.ECStep(algo, state) if isinstance(algo, ECConfig) else ga.GAStep(algo, state)
        self.generator = torch.Generator()
        self.generator.set_state(state["rng"])
        self.w1, self.w2 = state["w1"], state["w2"]
        self.population, self.generation, self.pending = state["population"], state["generation"], state["pending"]
        self.elites, self.total_steps, self.wall = list(state["elites"]), state["total_env_steps"], state["wall_time_s"]
        self.stats = state.get("obs_stats")  # None: raw observations (the paper's)
        self.elite_norms = [] if self.stats is None else list(zip(*state["elite_norms"]))
        self.spn = spn_from_config(algo.snn, algo.genome, spec, self.w1, self.w2)
        self.row: dict[str, Any] = {}
        self.started = time.perf_counter()
        self.since_row = {"steps": 0, "wall": self.wall}  # env steps run and wall time at the previous row
        self._norm: observations.Norm | None = None  # the statistics the population of the rollout asked sees
        self._at = ""  # the generation the rollout asked evaluates, for non-finite errors

    def elapsed(self) -> float:
        """Wall time of the run so far, earlier segments of a resumed run included."""
        return self.wall + time.perf_counter() - self.started

    def next_rollout(self) -> Rollout | None:
        """The genomes, env seeds and slots' observation normalisation (None: raw) of the next rollout: the next
        generation's population with the pending generation's re-evaluation, the last generation's re-evaluation
        alone, or None once the run is done. A non-finite GA genome stops the run (:meth:`Run.require_finite`)."""
        algo = self.cfg.algo
        parts: list[Rollout] = []
        if self.generation < algo.generations:
            self._norm = None if self.stats is None else observations.policy_norm(self.stats)
            seeds = episode_seeds(self.cfg.seed, self.generation + 1, FITNESS, algo.population)
            parts.append((self.population, seeds, _slots_norm(self._norm, algo.population)))
            self._at = f"generation {self.generation + 1}"
        else:
            self._at = f"generation {self.pending['generation']}" if self.pending is not None else ""
        if self.pending is not None:
            parts.append(self._reevaluation())
        if not parts:
            return None
        genomes = torch.cat([part[0] for part in parts])
        if isinstance(algo, GAConfig):  # EC's genomes are masks written as +-inf (ec.mask_genomes)
            self.run.require_finite(f"a genome of the population (algo.sigma={algo.sigma:g})", genomes, self._at)
        norms = [part[2] for part in parts]
        norm = None if norms[0] is None else (torch.cat([m for m, _ in norms]), torch.cat([s for _, s in norms]))
        return genomes, np.concatenate([part[1] for part in parts]), norm

    def take(self, result: Episodes) -> None:
        """The episodes of the rollout :meth:`next_rollout` asked for: step, record and checkpoint."""
        algo = self.cfg.algo
        self.run.require_finite("an episode return", result.returns, self._at)
        self.since_row["steps"] += result.total_steps
        if self.generation == algo.generations:  # the last generation's re-evaluation, alone
            self._finish(result)
            self.pending = None
            self._save()
            return
        n = algo.population
        fitness_eps = result.part(0, n)
        if self.pending is not None:
            self._finish(result.part(n, result.returns.numel()))
        if self.stats is not None:
            self.stats = observations.update(self.stats, observations.slot_moments(*fitness_eps.moments))
        self.generation += 1
        fitness = fitness_eps.returns
        pool, candidates = self.method.elite_pool(self.population, fitness)
        self.pending = {
            "generation": self.generation,
            "population": pool,
            "fitness": fitness,
            "steps": fitness_eps.total_steps,
            "candidates": candidates,
            **({} if self._norm is None else {"obs_norm": self._norm}),
        }
        self.population = self.method.advance(self.population, fitness, self.generator)
        self._save()

    def _reevaluation(self) -> Rollout:
        k, episodes, pending = self.cfg.algo.elite_candidates, self.cfg.algo.elite_episodes, self.pending
        genomes = ga.reevaluation_genomes(pending["population"], pending["candidates"], episodes)
        seeds = episode_seeds(self.cfg.seed, pending["generation"], REEVALUATION, k * episodes)
        return genomes, seeds, _slots_norm(pending.get("obs_norm"), k * episodes)

    def _finish(self, reeval: Episodes) -> None:
        """Pick the elite of the pending generation from its re-evaluation; record its row."""
        algo, pending = self.cfg.algo, self.pending
        k, episodes = algo.elite_candidates, algo.elite_episodes
        now = self.elapsed()
        candidates, fitness = pending["candidates"], pending["fitness"]
        elite_index, elite_return = ga.pick_elite(candidates, reeval.returns.view(k, episodes))
        elite = pending["population"][elite_index]
        self.elites.append(elite.clone())
        if self.stats is not None:
            self.elite_norms.append(pending["obs_norm"])
        slot = int((candidates == elite_index).nonzero()[0]) * episodes
        mask1, mask2 = self.spn.masks(elite[None])
        steps = pending["steps"] + reeval.total_steps
        self.total_steps += steps
        generation = pending["generation"]
        rate = spike_rate(
            reeval.spikes[slot : slot + episodes],
            reeval.steps[slot : slot + episodes],
            algo.snn.hidden,
            algo.snn.time_steps,
        )
        since = self.since_row
        self.row = {
            "generation": generation,
            "eval_return": elite_return,
            "best_fitness": float(fitness.max()),
            "mean_fitness": float(fitness.mean()),
            "env_steps": steps,
            "total_env_steps": self.total_steps,
            "wall_time_s": round(now, 3),
            "steps_per_s": round(since["steps"] / max(now - since["wall"], 1e-9), 1),
            "mask_density": mask_density(mask1, mask2),
            "spike_rate": rate,
            "synapses_l1": int(mask1.sum()),
            "synapses_l2": int(mask2.sum()),
            "elite_index": elite_index if self.method.elite_from_population else -1,
        }
        since.update(steps=0, wall=now)
        self.run.record(self.row, step=generation)
        log.info(
            "%sgen %d/%d  eval_return %.2f  best %.2f  mean %.2f  steps %d  %.0f steps/s  density %.3f  spike_rate %.3f",
            self.label,
            generation,
            algo.generations,
            elite_return,
            self.row["best_fitness"],
            self.row["mean_fitness"],
            self.total_steps,
            self.row["steps_per_s"],
            self.row["mask_density"],
            self.row["spike_rate"],
        )

    def _save(self) -> None:
        w1, w2, stats = self.w1, self.w2, self.stats
        self.run.save(
            {
                "generation": self.generation,
                "population": self.population,
                "pending": self.pending,
                "rng": self.generator.get_state(),
                "w1": w1,
                "w2": w2,
                "elites": torch.stack(self.elites) if self.elites else torch.empty(0, genome_size(w1, w2)),
                "total_env_steps": self.total_steps,
                "wall_time_s": self.elapsed(),
                **self.method.state(),
                **({} if stats is None else {"obs_stats": stats, "elite_norms": self._stacked_norms()}),
            }
        )

    def _stacked_norms(self) -> torch.Tensor:
        """Each elite's (mean, inv_std), [2, G, n]."""
        if not self.elite_norms:
            return torch.empty(2, 0, self.spec.n_obs)
        return torch.stack([torch.stack(list(part)) for part in zip(*self.elite_norms)])


def _slots_norm(norm: observations.Norm | None, count: int) -> observations.Norm | None:
    """``norm`` for ``count`` slots ([count, n] each), or None."""
    return None if norm is None else (norm[0].expand(count, -1), norm[1].expand(count, -1))
