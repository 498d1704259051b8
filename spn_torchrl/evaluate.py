"""Population rollouts: genomes -> episode return, env steps and hidden spike counts per individual."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np
import torch
from omegaconf import DictConfig
from torchrl.envs import EnvBase

from spn_torchrl.envs import TaskSpec, make_batched_env
from spn_torchrl.errors import ConfigError, require
from spn_torchrl.policies import PopulationSPN


@dataclass
class Episodes:
    """One episode per individual: undiscounted return, env steps and total hidden spikes."""

    returns: torch.Tensor
    steps: torch.Tensor
    spikes: torch.Tensor

    @property
    def total_steps(self) -> int:
        return int(self.steps.sum())

    def part(self, start: int, stop: int) -> Episodes:
        """The episodes of individuals ``start`` to ``stop - 1``."""
        return Episodes(self.returns[start:stop], self.steps[start:stop], self.spikes[start:stop])


def evaluation_slots(algo: DictConfig) -> int:
    """Env slots a GA run needs: its population and the previous generation's elite re-evaluation, which
    run in the same rollout."""
    return algo.population + algo.elite_candidates * algo.elite_episodes


def spike_rate(spikes: torch.Tensor, steps: torch.Tensor, hidden: int, time_steps: int) -> float:
    """Hidden spikes per neuron per simulation step over episodes (the rate the energy model uses)."""
    return float(spikes.sum() / (steps.sum() * hidden * time_steps))


def episode_seed(run_seed: int, generation: int, phase: int) -> int:
    """Env seed of one rollout, derived from the run seed so that a resumed run replays it exactly."""
    return int(np.random.SeedSequence([run_seed, generation, phase]).generate_state(1)[0] >> 1)


class PopulationEvaluator:
    """Runs a genome set on one batched env: every member to its own episode end, then frozen.

    The env (batch [P], or any shape of P slots, e.g. [workers, P/workers]) is built once and reused; it
    needs no transforms, as returns and steps are counted here. A call with fewer than P genomes leaves the
    remaining slots out of every result. Once some slots are idle, each step carries TorchRL's ``"_step"``
    mask: a backend that honours it (mujoco_batch, cartpole_batch) does not simulate them, others ignore it.
    """

    def __init__(self, env: EnvBase, spn: PopulationSPN, max_episode_steps: int) -> None:
        self.env = env
        self.spn = spn
        self.shape = env.batch_size
        self.size = env.batch_size.numel()
        self.max_episode_steps = max_episode_steps

    def __call__(self, genomes: torch.Tensor, seed: int) -> Episodes:
        count = genomes.shape[0]
        if not 0 < count <= self.size:
            raise ValueError(f"the env holds {self.size} individuals, got {count} genomes")
        self.spn.set_genomes(genomes)
        active = torch.arange(self.size) < count
        returns = torch.zeros(self.size)
        steps = torch.zeros(self.size, dtype=torch.long)
        spikes = torch.zeros(count)
        idle = self.size - count

        # a one-process env takes TorchRL's per-slot "_step" mask (the batch backends skip idle slots, GymWrapper
        # ignores it); a ParallelEnv only takes masks of whole workers, so it gets none
        masks = len(self.shape) == 1
        partial = masks and count < self.size
        self.env.set_seed(seed)
        td = self.env.reset()
        for _ in range(self.max_episode_steps):
            # the SPN called directly: spn_module's TensorDictModule wrapper costs more per step than the SNN
            action, hidden_spikes = self.spn(td.get("observation").reshape(self.size, -1)[:count])
            spikes += hidden_spikes * active[:count]
            if idle:  # the idle slots repeat the first action, a valid one that is never counted
                action = torch.cat([action, action[:1].expand(idle, *action.shape[1:])])
            td.set("action", action.reshape(*self.shape, *action.shape[1:]))
            if partial:
                td.set("_step", active.clone())
            stepped, td = self.env.step_and_maybe_reset(td)
            nxt = stepped.get("next")
            # float32 sums in step order, as TorchRL's RewardSum would give
            returns += nxt.get("reward").reshape(self.size).float() * active
            steps += active
            finished = nxt.get("done").reshape(self.size) & active
            if finished.any():
                active &= ~finished
                partial = masks
                if not active.any():
                    break
        return Episodes(returns[:count], steps[:count], spikes)

    def close(self) -> None:
        if not self.env.is_closed:
            self.env.close()


class Evaluator(Protocol):
    """What the GA loop needs: genomes [B, D] and an env seed in, one episode per genome out."""

    def __call__(self, genomes: torch.Tensor, seed: int) -> Episodes: ...

    def close(self) -> None: ...


def local_evaluator(cfg: DictConfig, spec: TaskSpec, spn: PopulationSPN) -> PopulationEvaluator:
    """One batched env of :func:`evaluation_slots` copies in this process."""
    env = make_batched_env(spec.env_id, evaluation_slots(cfg.algo), backend=cfg.env.backend, num_workers=cfg.env.num_workers)
    return PopulationEvaluator(env, spn, spec.max_episode_steps)


def ray_evaluator(cfg: DictConfig, spec: TaskSpec, spn: PopulationSPN) -> Evaluator:
    """The population sharded across Ray actors (spn_torchrl/ray_evaluator.py); needs the ``ray`` extra."""
    require("ray", "ray")
    from spn_torchrl.ray_evaluator import make_ray_evaluator

    return make_ray_evaluator(cfg, spec, spn)


EVALUATORS: dict[str, Callable[[DictConfig, TaskSpec, PopulationSPN], Evaluator]] = {
    "local": local_evaluator,
    "ray": ray_evaluator,
}


def make_evaluator(cfg: DictConfig, spec: TaskSpec, spn: PopulationSPN) -> Evaluator:
    """The evaluator named by ``evaluator.name``."""
    name = cfg.evaluator.name
    if name not in EVALUATORS:
        raise ConfigError(f"evaluator.name must be one of {sorted(EVALUATORS)}, got {name!r}")
    return EVALUATORS[name](cfg, spec, spn)
