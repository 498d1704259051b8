"""Task specs and the factory of batched TorchRL envs (one env of P copies of a task)."""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import gymnasium as gym
import torch
from torchrl.envs import (
    Compose,
    DoubleToFloat,
    EnvBase,
    GymWrapper,
    RewardSum,
    StepCounter,
    TransformedEnv,
)

from spn_torchrl.envs.cartpole import cartpole_batch_backend
from spn_torchrl.envs.mujoco import mujoco_batch_backend
from spn_torchrl.errors import ConfigError

TASKS = {
    "cartpole": "CartPole-v1",
    "halfcheetah": "HalfCheetah-v5",
    "swimmer": "Swimmer-v5",
    "humanoidstandup": "HumanoidStandup-v5",
}


@dataclass(frozen=True)
class TaskSpec:
    """What the policy and the GA need to know about a task."""

    env_id: str
    n_obs: int
    n_act: int
    discrete: bool
    max_episode_steps: int
    action_low: torch.Tensor | None
    action_high: torch.Tensor | None


def task_spec(env_id: str) -> TaskSpec:
    """Spec of a Gymnasium task id; a clear error for an id Gymnasium does not know."""
    try:
        spec = gym.spec(env_id)
    except gym.error.Error as err:
        raise ConfigError(
            f"env.id: unknown Gymnasium environment {env_id!r} (known tasks: {', '.join(TASKS.values())}): {err}"
        ) from None
    env = gym.make(env_id)
    try:
        obs_space, act_space = env.observation_space, env.action_space
        if not isinstance(obs_space, gym.spaces.Box) or len(obs_space.shape) != 1:
            raise ConfigError(f"env.id: {env_id} must have a flat Box observation space, got {obs_space}")
        if isinstance(act_space, gym.spaces.Discrete):
            return TaskSpec(env_id, obs_space.shape[0], int(act_space.n), True, spec.max_episode_steps, None, None)
        if isinstance(act_space, gym.spaces.Box) and len(act_space.shape) == 1:
            return TaskSpec(
                env_id,
                obs_space.shape[0],
                act_space.shape[0],
                False,
                spec.max_episode_steps,
                torch.as_tensor(act_space.low, dtype=torch.float32),
                torch.as_tensor(act_space.high, dtype=torch.float32),
            )
        raise ConfigError(f"env.id: {env_id} must have a Discrete or flat Box action space, got {act_space}")
    finally:
        env.close()


def gymnasium_backend(env_id: str, num_envs: int, num_workers: int = 1) -> EnvBase:
    """``GymWrapper`` around one ``SyncVectorEnv`` of ``num_envs`` copies, in this process (the evaluator's
    processes run several)."""
    if num_workers != 1:
        raise ConfigError(
            f"env.backend=gymnasium steps its copies in this process: env.num_workers must be 1, got {num_workers}"
        )
    venv = gym.vector.SyncVectorEnv(
        [functools.partial(gym.make, env_id) for _ in range(num_envs)],
        autoreset_mode=gym.vector.AutoresetMode.DISABLED,
    )
    return GymWrapper(venv, categorical_action_encoding=True)


BACKENDS: dict[str, Callable[..., EnvBase]] = {
    "gymnasium": gymnasium_backend,
    "mujoco_batch": mujoco_batch_backend,  # HalfCheetah, Swimmer, HumanoidStandup v5 only
    "cartpole_batch": cartpole_batch_backend,  # CartPole-v1 only
}


def make_batched_env(env_id: str, num_envs: int, *, backend: str = "gymnasium", num_workers: int = 1) -> EnvBase:
    """One TorchRL env of ``num_envs`` copies of a task from ``backend``, without transforms (what
    :class:`~spn_torchrl.evaluation.rollout.PopulationEvaluator` steps); discrete actions are indices."""
    if backend not in BACKENDS:
        raise ConfigError(f"env.backend: unknown backend {backend!r}, expected one of {sorted(BACKENDS)}")
    return BACKENDS[backend](env_id, num_envs, num_workers)


def make_population_env(env_id: str, num_envs: int, *, backend: str = "gymnasium", num_workers: int = 1) -> EnvBase:
    """:func:`make_batched_env` with ``DoubleToFloat``, ``StepCounter`` and ``RewardSum``."""
    base = make_batched_env(env_id, num_envs, backend=backend, num_workers=num_workers)
    return TransformedEnv(base, Compose(DoubleToFloat(), StepCounter(), RewardSum()))
