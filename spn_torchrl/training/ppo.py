"""A PPO run for the DPN baseline and for Connections-PPO, from TorchRL's parts (Collector, GAE, ClipPPOLoss).

Follows the paper's appendix (Spinning Up's PPO): one env, ``frames_per_batch`` steps per iteration from a
reset (Spinning Up resets at every epoch end, which also makes a resumed run exact), advantages computed once
per iteration, ``epochs`` passes over minibatches, one Adam with a learning rate per network.

With ``normalize_observations`` the actor's and the critic's networks start with an
:class:`~spn_torchrl.snn.observations.ObservationNormalizer`: an iteration collects and trains with the running
statistics as they stood before it, which are then updated from the observations it collected (as a GA or EC
generation's); the checkpoint keeps the statistics (``obs_stats``) and the networks' buffers.
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import torch
from tensordict import TensorDictBase
from tensordict.nn import AddStateIndependentNormalScale, TensorDictModuleBase, TensorDictSequential
from torch import nn
from torchrl.collectors import Collector
from torchrl.data import LazyTensorStorage, ReplayBuffer, SamplerWithoutReplacement
from torchrl.envs import EnvBase, ExplorationType, set_exploration_type
from torchrl.modules import IndependentNormal, ProbabilisticActor
from torchrl.objectives import ClipPPOLoss
from torchrl.objectives.value import GAE

from spn_torchrl import checkpoint
from spn_torchrl.config import RunConfig
from spn_torchrl.envs import TaskSpec, make_transformed_env, task_spec
from spn_torchrl.lifecycle import Run, open_run
from spn_torchrl.seeds import COLLECTION, EVALUATION, episode_seed
from spn_torchrl.snn import observations
from spn_torchrl.snn.observations import ObservationNormalizer
from spn_torchrl.snn.policies import TrainableSPN, init_fixed_weights, mask_density, spn_from_config
from spn_torchrl.snn.surrogate import surrogate_spike

log = logging.getLogger("spn_torchrl")

COUNTERS = ("policy_forward", "policy_backward", "value_forward", "value_backward", "eval_policy_forward")


class Keyed(TensorDictModuleBase):
    """A network read from ``in_keys`` and written to ``out_keys`` of a tensordict, the role of TensorDictModule.

    TensorDictModule passes every output through ``TensorDict.from_any``, which (tensordict 0.14) searches
    sys.path for pandas on each call where pandas is not installed: about half an actor step here. This
    writes the outputs as they are, with the same parameter names (``module.*``), so checkpoints carry over.
    """

    def __init__(self, module: nn.Module, in_keys: list[str], out_keys: list[str]) -> None:
        super().__init__()
        self.module = module
        self.in_keys = list(in_keys)
        self.out_keys = list(out_keys)

    def forward(self, tensordict: TensorDictBase) -> TensorDictBase:
        out = self.module(*(tensordict.get(key) for key in self.in_keys))
        for key, value in zip(self.out_keys, out if isinstance(out, tuple) else (out,), strict=True):
            tensordict.set(key, value)
        return tensordict


def dpn(n_obs: int, n_act: int, hidden: int, discrete: bool) -> nn.Module:
    """The paper's DPN: n -> hidden ReLU -> m Tanh (the Gaussian mean); logits (no Tanh) for discrete tasks."""
    layers: list[nn.Module] = [nn.Linear(n_obs, hidden), nn.ReLU(), nn.Linear(hidden, n_act)]
    return nn.Sequential(*layers) if discrete else nn.Sequential(*layers, nn.Tanh())


def spn_net(cfg: RunConfig, spec: TaskSpec) -> TrainableSPN:
    """The GA's SPN for this seed (same generator, same fixed weights) with trainable scores drawn after them."""
    algo = cfg.algo
    generator = torch.Generator().manual_seed(cfg.seed)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, algo.snn.hidden, generator)
    spn = spn_from_config(algo.snn, "connections", spec, w1, w2)
    scores = algo.score_init_std * torch.randn(spn.genome_size, generator=generator)
    return TrainableSPN(spn, scores, surrogate_spike(algo.surrogate, algo.surrogate_alpha))


def normalized(net: nn.Module, size: int, normalize: bool) -> nn.Module:
    """``net`` behind an observation normaliser of ``size`` observations where ``normalize``, else ``net``."""
    return nn.Sequential(ObservationNormalizer(size), net) if normalize else net


def make_actor(cfg: RunConfig, spec: TaskSpec, env: EnvBase) -> ProbabilisticActor:
    """The stochastic policy: Gaussian (state-independent log-std) around the net's output, or Categorical."""
    algo = cfg.algo
    net = spn_net(cfg, spec) if algo.policy == "spn" else dpn(spec.n_obs, spec.n_act, algo.hidden, spec.discrete)
    net = normalized(net, spec.n_obs, cfg.normalize_observations)
    action_spec = env.full_action_spec_unbatched
    if spec.discrete:
        module = Keyed(net, in_keys=["observation"], out_keys=["logits"])
        return ProbabilisticActor(
            module,
            in_keys=["logits"],
            spec=action_spec,
            distribution_class=torch.distributions.Categorical,
            return_log_prob=True,
        )
    module = TensorDictSequential(
        Keyed(net, in_keys=["observation"], out_keys=["loc_net"]),
        Keyed(
            AddStateIndependentNormalScale(spec.n_act, scale_lb=1e-6, init_value=algo.log_std_init),
            in_keys=["loc_net"],
            out_keys=["loc", "scale"],
        ),
    )
    return ProbabilisticActor(
        module, in_keys=["loc", "scale"], spec=action_spec, distribution_class=IndependentNormal, return_log_prob=True
    )


def make_critic(spec: TaskSpec, hidden: int, normalize: bool = False) -> Keyed:
    """The paper's value net: n -> hidden ReLU -> 1, as TorchRL's value operator (observation -> state_value);
    ``normalize``: behind an observation normaliser."""
    net = nn.Sequential(nn.Linear(spec.n_obs, hidden), nn.ReLU(), nn.Linear(hidden, 1))
    return Keyed(normalized(net, spec.n_obs, normalize), in_keys=["observation"], out_keys=["state_value"])


def set_norm(norm: observations.Norm, *modules: nn.Module) -> None:
    """Give every observation normaliser in ``modules`` the normalisation ``norm``."""
    for module in modules:
        for part in module.modules():
            if isinstance(part, ObservationNormalizer):
                part.set(norm)


def evaluate_policy(actor: ProbabilisticActor, env: EnvBase, max_steps: int, seed: int) -> tuple[torch.Tensor, int]:
    """Undiscounted return of the first episode of each env copy, with the deterministic policy (the mean),
    and the number of policy samples the rollout took."""
    env.set_seed(seed)
    with torch.no_grad(), set_exploration_type(ExplorationType.DETERMINISTIC):
        td = env.rollout(max_steps, actor, break_when_any_done=False)
    done = td["next", "done"].squeeze(-1)  # [E, T]
    if not bool(done.any(-1).all()):
        raise RuntimeError(f"an evaluation episode did not end within {max_steps} steps")
    first = done.float().argmax(-1)
    returns = td["next", "episode_reward"].squeeze(-1)
    return returns.gather(-1, first[:, None]).squeeze(-1), done.numel()


@dataclass
class Counts:
    """Cumulative network passes, in samples (what the energy model needs)."""

    values: dict[str, int] = field(default_factory=lambda: dict.fromkeys(COUNTERS, 0))

    def add(self, **kwargs: int) -> None:
        for key, value in kwargs.items():
            self.values[key] += int(value)


def run_meta(cfg: RunConfig, spec: TaskSpec) -> dict[str, Any]:
    """What a checkpoint must match to be resumed by this config (beyond the config contract)."""
    algo = cfg.algo
    return {
        "format": checkpoint.PPO_FORMAT,
        "env_id": spec.env_id,
        "policy": algo.policy,
        "n_obs": spec.n_obs,
        "n_act": spec.n_act,
        "hidden": algo.hidden,
    }


def train_ppo(cfg: RunConfig, run_dir: Path, run_name: str) -> dict[str, Any]:
    """Run (or resume) PPO; returns the last iteration's metrics."""
    spec = task_spec(cfg.env.id)
    iterations = cfg.algo.total_env_steps // cfg.algo.frames_per_batch
    with open_run(cfg, run_dir, run_name, "ppo", run_meta(cfg, spec), iterations) as run:
        done = 0 if run.state is None else run.state["iteration"]  # at most iterations: open_run refuses fewer
        if done == iterations:
            log.info("%s already ran its %d iterations", run_dir, iterations)
            return run.rows[-1] if run.rows else {}
        if run.state is not None:
            log.info("resuming %s after iteration %d", run_dir, done)
        return _iterations(cfg, spec, run, done, iterations)


def _iterations(cfg: RunConfig, spec: TaskSpec, run: Run, start: int, iterations: int) -> dict[str, Any]:
    """PPO from iteration ``start`` to ``iterations``, recording each iteration's row and checkpoint."""
    algo = cfg.algo
    torch.manual_seed(cfg.seed)
    env = make_transformed_env(spec.env_id, 1, backend=cfg.env.backend)
    eval_env = make_transformed_env(spec.env_id, algo.eval_episodes, backend=cfg.env.backend)
    actor = make_actor(cfg, spec, env)
    critic = make_critic(spec, algo.hidden, cfg.normalize_observations)
    loss_module = ClipPPOLoss(
        actor,
        critic,
        clip_epsilon=algo.clip_epsilon,
        entropy_bonus=False,
        critic_coeff=1.0,
        loss_critic_type="l2",
        normalize_advantage=algo.normalize_advantage,
        functional=False,
    )
    gae = GAE(gamma=algo.gamma, lmbda=algo.gae_lambda, value_network=critic, average_gae=False)
    optim = torch.optim.Adam(
        [{"params": actor.parameters(), "lr": algo.lr_policy}, {"params": critic.parameters(), "lr": algo.lr_value}]
    )
    params = [*actor.parameters(), *critic.parameters()]
    lrs = f"algo.lr_policy={algo.lr_policy:g}, algo.lr_value={algo.lr_value:g}"
    counts = Counts()
    wall = 0.0
    stats = observations.initial_stats(spec.n_obs) if cfg.normalize_observations else None
    if run.state is not None:
        state = run.state
        load_states(run.dir, state, actor=actor, critic=critic, optim=optim)
        counts.values.update(state["counts"])
        wall = state["wall_time_s"]
        torch.set_rng_state(state["torch_rng"])
        stats = state.get("obs_stats")
    if stats is not None:
        set_norm(observations.policy_norm(stats), actor, critic)

    next_iteration = [start + 1]

    def seed_iteration() -> None:
        # every iteration starts from a reset seeded by (run seed, iteration): a resumed run replays it
        env.set_seed(episode_seed(cfg.seed, next_iteration[0], COLLECTION))

    collector = Collector(
        env,
        actor,
        frames_per_batch=algo.frames_per_batch,
        total_frames=(iterations - start) * algo.frames_per_batch,
        reset_at_each_iter=True,
        pre_collect_hook=seed_iteration,
        auto_register_policy_transforms=False,
    )
    buffer = ReplayBuffer(
        storage=LazyTensorStorage(algo.frames_per_batch),
        sampler=SamplerWithoutReplacement(),
        batch_size=algo.minibatch_size,
    )
    row: dict[str, Any] = {}
    t0 = time.perf_counter()
    try:
        for iteration, data in enumerate(collector, start=start + 1):
            frames = data.numel()
            counts.add(policy_forward=frames)
            data = data.reshape(-1)
            with torch.no_grad():
                data = gae(data)
            counts.add(value_forward=2 * frames)  # values of obs and next obs
            buffer.empty()
            buffer.extend(data)
            sums: dict[str, float] = {"loss_objective": 0.0, "loss_critic": 0.0, "kl_approx": 0.0, "clip_fraction": 0.0}
            updates = 0
            for _ in range(algo.epochs):
                for _ in range(frames // algo.minibatch_size):
                    batch = buffer.sample()
                    loss = loss_module(batch)
                    total = loss["loss_objective"] + loss["loss_critic"]
                    run.require_finite("the PPO loss", total.detach(), f"iteration {iteration}")
                    optim.zero_grad()
                    total.backward()
                    optim.step()
                    run.require_finite(f"a network parameter ({lrs})", params, f"iteration {iteration}")
                    n = batch.numel()
                    counts.add(policy_forward=n, policy_backward=n, value_forward=n, value_backward=n)
                    for key in sums:
                        if key in loss.keys():
                            sums[key] += float(loss[key].detach())
                    updates += 1
            if stats is not None:  # the next iteration's policy sees the statistics of every observation so far
                stats = observations.update(stats, observations.moments(data["observation"]))
                set_norm(observations.policy_norm(stats), actor, critic)
            collector.update_policy_weights_()
            done = data["next", "done"].squeeze(-1)
            finished = data["next", "episode_reward"].squeeze(-1)[done]
            eval_return = math.nan
            # every eval_interval-th iteration only: which iterations are evaluated must not depend on the budget,
            # so a run extended to a larger budget writes the rows (and energy counts) of a straight run
            if iteration % algo.eval_interval == 0:
                returns, samples = evaluate_policy(
                    actor, eval_env, spec.max_episode_steps, episode_seed(cfg.seed, iteration, EVALUATION)
                )
                counts.add(eval_policy_forward=samples)
                eval_return = float(returns.mean())
                run.require_finite("the evaluation return", eval_return, f"iteration {iteration}")
            t1 = time.perf_counter()
            seconds, t0 = t1 - t0, t1
            wall += seconds
            row = {
                "iteration": iteration,
                "total_env_steps": iteration * algo.frames_per_batch,
                "eval_return": eval_return,
                "train_return": float(finished.mean()) if finished.numel() else math.nan,
                "train_episodes": int(finished.numel()),
                **{key: value / updates for key, value in sums.items()},
                "log_std": float(_log_std(actor)) if not spec.discrete else math.nan,
                "mask_density": _mask_density(actor),
                "wall_time_s": round(wall, 3),
                "steps_per_s": round(frames / seconds, 1),
                **counts.values,
            }
            run.record(row, step=iteration, prefix={"eval_return": "eval"})
            run.save(
                {
                    "iteration": iteration,
                    "actor": actor.state_dict(),
                    "critic": critic.state_dict(),
                    "optim": optim.state_dict(),
                    "torch_rng": torch.get_rng_state(),
                    "counts": dict(counts.values),
                    "wall_time_s": wall,
                    **({} if stats is None else {"obs_stats": stats}),
                }
            )
            next_iteration[0] = iteration + 1
            log.info(
                "iter %d/%d  steps %d  eval %.2f  train %.2f  loss_pi %.4f  loss_v %.4f  %.0f steps/s",
                iteration,
                iterations,
                row["total_env_steps"],
                eval_return,
                row["train_return"],
                row["loss_objective"],
                row["loss_critic"],
                row["steps_per_s"],
            )
    finally:
        collector.shutdown()
        eval_env.close()
    return row


def _log_std(actor: ProbabilisticActor) -> torch.Tensor:
    """Mean log-std of the Gaussian policy."""
    for module in actor.modules():
        if isinstance(module, AddStateIndependentNormalScale):
            return module.state_independent_scale.detach().mean()
    return torch.tensor(math.nan)


def _mask_density(actor: ProbabilisticActor) -> float:
    """Fraction of existing synapses of a trainable SPN (NaN for the DPN)."""
    for module in actor.modules():
        if isinstance(module, TrainableSPN):
            with torch.no_grad():
                return mask_density(*module.masks())
    return math.nan


def load_actor(run_dir: Path, cfg: RunConfig) -> tuple[ProbabilisticActor, TaskSpec]:
    """The trained stochastic actor of a PPO run's checkpoint (use the DETERMINISTIC exploration type to act)."""
    spec = task_spec(cfg.env.id)
    state = checkpoint.load(run_dir, expected=run_meta(cfg, spec))
    env = make_transformed_env(spec.env_id, 1, backend=cfg.env.backend)
    try:
        actor = make_actor(cfg, spec, env)
    finally:
        env.close()
    load_states(run_dir, state, actor=actor)
    return actor, spec


def load_states(run_dir: Path, state: dict[str, Any], **targets: Any) -> None:
    """Load each module's or optimiser's entry of a PPO checkpoint's ``state``; one of other names or shapes
    is a damaged checkpoint (CheckpointError)."""
    for key, target in targets.items():
        try:
            target.load_state_dict(state[key])
        except (RuntimeError, ValueError, KeyError, TypeError, IndexError) as err:
            problem = f"'{key}' does not fit the {key} this config builds: {type(err).__name__}"
            raise checkpoint.damaged(
                Path(run_dir) / checkpoint.CHECKPOINT_NAME, checkpoint.PPO_FORMAT, problem
            ) from None
