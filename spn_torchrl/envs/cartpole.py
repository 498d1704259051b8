"""A TorchRL env of P copies of Gymnasium's CartPole-v1, stepped as numpy arrays in one call.

Replicates ``gym.make("CartPole-v1")`` (default kwargs): the same float64 Euler dynamics written as array
operations, reward 1 per step (0 for a step after termination), the termination bounds, the reset
distribution and the 500-step time limit; slots, seeding and masks as :class:`~spn_torchrl.envs.batch.BatchEnv`.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from torchrl.data import Categorical

from spn_torchrl.envs.batch import BatchEnv, rows
from spn_torchrl.errors import ConfigError

ENV_ID = "CartPole-v1"
# Gymnasium's constants, derived as CartPoleEnv derives them
GRAVITY = 9.8
MASSCART = 1.0
MASSPOLE = 0.1
TOTAL_MASS = MASSPOLE + MASSCART
LENGTH = 0.5  # half the pole's length
POLEMASS_LENGTH = MASSPOLE * LENGTH
FORCE_MAG = 10.0
TAU = 0.02
THETA_THRESHOLD = 12 * 2 * math.pi / 360
X_THRESHOLD = 2.4
RESET_BOUND = 0.05


class CartPoleBatchEnv(BatchEnv):
    """P CartPoles as a TorchRL env of batch size [P]; actions are indices (0: push left, 1: push right)."""

    def __init__(self, num_envs: int, max_episode_steps: int = 500) -> None:
        action_spec = Categorical(2, shape=(num_envs,), dtype=torch.int64)
        super().__init__(num_envs, 4, action_spec, max_episode_steps)
        self.env_id = ENV_ID
        self._fallen = np.zeros(num_envs, dtype=bool)  # terminated once since the reset (no more reward)

    def _reset_slots(self, ids: np.ndarray | None) -> None:
        self._fallen[rows(ids)] = False
        for slot in self._all[rows(ids)]:
            self._obs[slot] = self._rngs[slot].uniform(low=-RESET_BOUND, high=RESET_BOUND, size=(4,))

    def _advance(self, ids: np.ndarray | None, action: np.ndarray) -> None:
        slots = rows(ids)
        x, x_dot, theta, theta_dot = self._obs[slots].T
        force = np.where(action == 1, FORCE_MAG, -FORCE_MAG)
        costheta = np.cos(theta)
        sintheta = np.sin(theta)
        temp = (force + POLEMASS_LENGTH * np.square(theta_dot) * sintheta) / TOTAL_MASS
        thetaacc = (GRAVITY * sintheta - costheta * temp) / (
            LENGTH * (4.0 / 3.0 - MASSPOLE * np.square(costheta) / TOTAL_MASS)
        )
        xacc = temp - POLEMASS_LENGTH * thetaacc * costheta / TOTAL_MASS
        x, x_dot = x + TAU * x_dot, x_dot + TAU * xacc
        theta, theta_dot = theta + TAU * theta_dot, theta_dot + TAU * thetaacc
        self._obs[slots] = np.stack([x, x_dot, theta, theta_dot], axis=1)
        terminated = (x < -X_THRESHOLD) | (x > X_THRESHOLD) | (theta < -THETA_THRESHOLD) | (theta > THETA_THRESHOLD)
        self._reward[slots] = np.where(terminated & self._fallen[slots], 0.0, 1.0)
        self._terminated[slots] = terminated
        self._fallen[slots] |= terminated


def cartpole_batch_backend(env_id: str, num_envs: int, threads: int = 1) -> CartPoleBatchEnv:
    """Backend factory: CartPole-v1 only, in one thread."""
    if env_id != ENV_ID:
        raise ConfigError(
            f"env.backend=cartpole_batch steps {ENV_ID} only, not env.id={env_id!r}: use env.backend=gymnasium"
        )
    if threads != 1:
        raise ConfigError(
            f"env.backend=cartpole_batch steps every copy in one numpy call: env.threads must be 1, got {threads}"
        )
    return CartPoleBatchEnv(num_envs)
