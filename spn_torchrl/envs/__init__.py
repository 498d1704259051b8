"""Tasks and their envs: task specs, the backend registry, and the factory of batched TorchRL envs (P copies of a
task in one env). A new backend is a module here and an entry in ``BACKENDS`` (and its name in ``config.BACKENDS``)."""

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

from spn_torchrl.envs.cartpole import ENV_ID as CARTPOLE_ID
from spn_torchrl.envs.cartpole import cartpole_batch_backend
from spn_torchrl.envs.gym_v2 import V2_TASKS, check_gym_v2, gym_v2_backend
from spn_torchrl.envs.mujoco import BATCH_TASKS, mujoco_batch_backend
from spn_torchrl.envs.mujoco210 import MJ210_TASKS, mujoco210_backend
from spn_torchrl.envs.mujoco_warp import WARP_SIZES, mujoco_warp_backend
from spn_torchrl.errors import ConfigError

TASKS = {
    "cartpole": "CartPole-v1",
    "halfcheetah": "HalfCheetah-v5",
    "swimmer": "Swimmer-v5",
    "humanoidstandup": "HumanoidStandup-v5",
    # beyond the paper (issue 46): the locomotion tasks, with their healthy-state termination
    "hopper": "Hopper-v5",
    "walker2d": "Walker2d-v5",
    "ant": "Ant-v5",
    "humanoid": "Humanoid-v5",
    "invertedpendulum": "InvertedPendulum-v5",
    "inverteddoublependulum": "InvertedDoublePendulum-v5",
    "reacher": "Reacher-v5",
    "pusher": "Pusher-v5",
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
    """Spec of a Gymnasium task id (or a Gym 0.21 v2 id of env.backend=gym_v2); a clear error for an id Gymnasium
    does not know."""
    if env_id in V2_TASKS:  # Gymnasium registers the v2 ids only to refuse them
        v2 = V2_TASKS[env_id]
        bound = torch.full((v2.n_act,), v2.action_bound)
        return TaskSpec(env_id, v2.n_obs, v2.n_act, False, v2.max_episode_steps, -bound, bound)
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


def gymnasium_backend(env_id: str, num_envs: int, threads: int = 1) -> EnvBase:
    """``GymWrapper`` around one ``SyncVectorEnv`` of ``num_envs`` copies, in this process (the evaluator's
    processes run several)."""
    if threads != 1:
        raise ConfigError(f"env.backend=gymnasium steps its copies in one thread: env.threads must be 1, got {threads}")
    venv = gym.vector.SyncVectorEnv(
        [functools.partial(gym.make, env_id) for _ in range(num_envs)],
        autoreset_mode=gym.vector.AutoresetMode.DISABLED,
    )
    return GymWrapper(venv, categorical_action_encoding=True)


@dataclass(frozen=True)
class Backend:
    """An env backend: its factory ``(env_id, num_envs, threads[, device]) -> env``, the ids it supports (None:
    any), whether it runs on ``env.device`` (else on the CPU) and a check of what it needs beyond the config
    (``check(env_id)`` raises ConfigError)."""

    factory: Callable[..., EnvBase]
    env_ids: tuple[str, ...] | None = None
    on_device: bool = False
    check: Callable[[str], None] | None = None


BACKENDS: dict[str, Backend] = {
    "gymnasium": Backend(gymnasium_backend),
    "mujoco_batch": Backend(mujoco_batch_backend, tuple(BATCH_TASKS)),
    "cartpole_batch": Backend(cartpole_batch_backend, (CARTPOLE_ID,)),
    "mujoco_warp": Backend(mujoco_warp_backend, tuple(WARP_SIZES), on_device=True),  # the gpu extra
    "gym_v2": Backend(gym_v2_backend, tuple(V2_TASKS), check=check_gym_v2),  # scripts/make_gym_v2_env.sh
    "mujoco_batch_mj210": Backend(mujoco210_backend, tuple(MJ210_TASKS)),  # MuJoCo 2.1.0's body inertias
}


def check_backend(backend: str, env_id: str) -> None:
    """ConfigError unless ``backend`` exists and steps ``env_id`` (before any env is built)."""
    if backend not in BACKENDS:
        raise ConfigError(f"env.backend must be one of {', '.join(BACKENDS)}, got {backend!r}")
    ids = BACKENDS[backend].env_ids
    if ids is not None and env_id not in ids:
        raise ConfigError(
            f"env.backend={backend} steps {', '.join(ids)} only, not env.id={env_id!r}: use env.backend=gymnasium"
        )
    if BACKENDS[backend].check is not None:
        BACKENDS[backend].check(env_id)


def make_batched_env(
    env_id: str, num_envs: int, *, backend: str = "gymnasium", threads: int = 1, device: str = "cpu"
) -> EnvBase:
    """One TorchRL env of ``num_envs`` copies of a task from ``backend``, without transforms (what
    :class:`~spn_torchrl.evaluation.rollout.PopulationEvaluator` steps); discrete actions are indices."""
    check_backend(backend, env_id)
    if BACKENDS[backend].on_device:
        return BACKENDS[backend].factory(env_id, num_envs, threads, device)
    if device != "cpu":
        raise ConfigError(f"env.device={device} needs env.backend=mujoco_warp; env.backend={backend} runs on the CPU")
    return BACKENDS[backend].factory(env_id, num_envs, threads)


def make_transformed_env(env_id: str, num_envs: int, *, backend: str = "gymnasium") -> EnvBase:
    """:func:`make_batched_env` with ``DoubleToFloat``, ``StepCounter`` and ``RewardSum`` (PPO's envs)."""
    base = make_batched_env(env_id, num_envs, backend=backend)
    return TransformedEnv(base, Compose(DoubleToFloat(), StepCounter(), RewardSum()))
