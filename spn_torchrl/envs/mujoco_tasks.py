"""Gymnasium v5 tasks with their own terms on the mujoco_batch backend (default kwargs): the locomotion tasks Hopper,
Walker2d, Ant and Humanoid, InvertedPendulum and InvertedDoublePendulum, Reacher and Pusher.

Each :class:`Terms` holds what its Gymnasium source (gymnasium/envs/mujoco/hopper_v5.py, walker2d_v5.py, ant_v5.py,
humanoid_v5.py, inverted_pendulum_v5.py, inverted_double_pendulum_v5.py, reacher_v5.py, pusher_v5.py) computes
after ``do_simulation``: the position its forward reward differentiates, the observation, and the reward with the
healthy state whose loss terminates the episode (the locomotion tasks' ``terminate_when_unhealthy=True``; the
pendulums' fall; Reacher and Pusher never terminate), and the reset draw of a task whose ``reset_model`` is its own
(Reacher's goal, Pusher's cylinder). Every
term is Gymnasium's expression on rows of slots, in its order and dtypes (the control cost of a float32 action is
float32, as Gymnasium's is), so the envs equal Gymnasium's bit for bit (tests/test_mujoco_batch.py). The
simulations (``sims``) are :class:`~spn_torchrl.envs.mujoco.BatchSimulations` or, for the tasks that read contact
forces, :class:`~spn_torchrl.envs.mujoco.DataSimulations`: [P, ...] arrays of ``qpos``, ``qvel``, ``ctrl`` and
``fields``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import mujoco
import numpy as np

Slots = slice | np.ndarray  # the rows of the stepped simulations (batch.rows)


@dataclass(frozen=True)
class Terms:
    """A task's own terms: the position its forward reward differentiates, its observation and its reward with the
    healthy state that ends an episode."""

    # MjData fields the terms read beyond qpos, qvel and ctrl; any that mj_rnePostConstraint computes (cfrc_ext)
    # puts the task on DataSimulations
    fields: tuple[str, ...]
    position: Callable[[mujoco.MjModel, Any, Slots], np.ndarray | float]  # (model, sims, slots) -> x [k] (or 0.0)
    observe: Callable[[mujoco.MjModel, Any, Slots], list[np.ndarray]]  # -> the observation's parts, rows [k, ...]
    # (model, sims, slots, action [k, nu] float32, x_velocity [k], ctrl_cost_weight) -> (reward [k], healthy [k])
    reward: Callable[[mujoco.MjModel, Any, Slots, np.ndarray, np.ndarray, float], tuple[np.ndarray, np.ndarray]]
    size: Callable[[mujoco.MjModel], int]  # the observation's length
    # (model, a slot's generator) -> its initial qpos [nq], qvel [nv]; None: mujoco.initial_state's noise draw
    reset: Callable[[mujoco.MjModel, np.random.Generator], tuple[np.ndarray, np.ndarray]] | None = None


def com_parts(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """The com-based part of Humanoid's and HumanoidStandup's observation: ``cinert``, ``cvel``,
    ``qfrc_actuator[6:]`` and ``cfrc_ext`` of every body but the world."""
    bodies = model.nbody - 1
    return [
        sims.cinert[slots, 1:].reshape(-1, bodies * 10),
        sims.cvel[slots, 1:].reshape(-1, bodies * 6),
        sims.qfrc_actuator[slots, 6:],
        sims.cfrc_ext[slots, 1:].reshape(-1, bodies * 6),
    ]


def com_size(model: mujoco.MjModel) -> int:
    """Length of the Humanoid observation: qpos[2:], qvel and :func:`com_parts`."""
    return model.nq - 2 + model.nv + (model.nbody - 1) * (10 + 6 + 6) + (model.nv - 6)


def _qpos_x(model: mujoco.MjModel, sims: Any, slots: Slots) -> np.ndarray:
    return sims.qpos[slots, 0]


def _planar_obs(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """Hopper's and Walker2d's ``_get_obs``: qpos[1:] and qvel clipped to [-10, 10]."""
    return [sims.qpos[slots, 1:], np.clip(sims.qvel[slots], -10, 10)]


def _planar_size(model: mujoco.MjModel) -> int:
    return model.nq - 1 + model.nv


def _planar_reward(
    healthy: np.ndarray, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> np.ndarray:
    """Hopper's and Walker2d's ``_get_rew``: forward (weight 1) + healthy (1 while healthy) - control cost."""
    rewards = 1.0 * x_velocity + healthy * 1.0
    return rewards - ctrl_cost_weight * np.sum(np.square(action), axis=-1)


def _hopper_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """hopper_v5: healthy while every state but x and z is in (-100, 100), z in (0.7, inf), angle in (-0.2, 0.2)."""
    qpos, qvel = sims.qpos[slots], sims.qvel[slots]
    state = np.concatenate([qpos[:, 2:], qvel], axis=1)
    z, angle = qpos[:, 1], qpos[:, 2]
    healthy = (
        np.all((-100.0 < state) & (state < 100.0), axis=1) & (0.7 < z) & (z < np.inf) & (-0.2 < angle) & (angle < 0.2)
    )
    return _planar_reward(healthy, action, x_velocity, ctrl_cost_weight), healthy


def _walker2d_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """walker2d_v5: healthy while z is in (0.8, 2.0) and the angle in (-1, 1)."""
    z, angle = sims.qpos[slots, 1], sims.qpos[slots, 2]
    healthy = (0.8 < z) & (z < 2.0) & (-1.0 < angle) & (angle < 1.0)
    return _planar_reward(healthy, action, x_velocity, ctrl_cost_weight), healthy


def _torso_x(model: mujoco.MjModel, sims: Any, slots: Slots) -> np.ndarray:
    """ant_v5's ``data.body(main_body=1).xpos[0]``."""
    return sims.xpos[slots, 1, 0]


def _ant_contact_forces(sims: Any, slots: Slots) -> np.ndarray:
    """ant_v5's ``contact_forces``: ``cfrc_ext`` clipped to [-1, 1], every body (the world's too), [k, nbody, 6]."""
    return np.clip(sims.cfrc_ext[slots], -1.0, 1.0)


def _ant_obs(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """ant_v5's ``_get_obs``: qpos[2:], qvel and the clipped contact forces of every body but the world."""
    forces = _ant_contact_forces(sims, slots)[:, 1:]
    return [sims.qpos[slots, 2:], sims.qvel[slots], forces.reshape(len(forces), -1)]


def _ant_size(model: mujoco.MjModel) -> int:
    return model.nq - 2 + model.nv + (model.nbody - 1) * 6


def _ant_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """ant_v5: forward (weight 1) + healthy (1) - control cost - contact cost (5e-4 of the clipped forces'
    squares); healthy while the state is finite and z is in [0.2, 1.0]."""
    qpos, qvel = sims.qpos[slots], sims.qvel[slots]
    z = qpos[:, 2]
    healthy = np.isfinite(qpos).all(axis=1) & np.isfinite(qvel).all(axis=1) & (0.2 <= z) & (z <= 1.0)
    rewards = x_velocity * 1 + healthy * 1.0
    forces = _ant_contact_forces(sims, slots)
    contact_cost = 5e-4 * np.sum(np.square(forces).reshape(len(forces), -1), axis=-1)
    costs = ctrl_cost_weight * np.sum(np.square(action), axis=-1) + contact_cost
    return rewards - costs, healthy


def _mass_center_x(model: mujoco.MjModel, sims: Any, slots: Slots) -> np.ndarray:
    """humanoid_v5's ``mass_center``'s x: the body masses' weighted mean of ``xipos``, per simulation as
    Gymnasium sums it."""
    mass, total = model.body_mass, model.body_mass.sum()
    return np.array([(np.einsum("b,bj->j", mass, xipos) / total)[0] for xipos in sims.xipos[slots]])


def _humanoid_obs(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """humanoid_v5's ``_get_obs``: qpos[2:], qvel and :func:`com_parts`."""
    return [sims.qpos[slots, 2:], sims.qvel[slots], *com_parts(model, sims, slots)]


def _humanoid_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """humanoid_v5: forward (weight 1.25) + healthy (5) - control cost (of ``data.ctrl``'s squares) - contact
    cost (5e-7 of every body's ``cfrc_ext`` squares, at most 10); healthy while z is in (1.0, 2.0)."""
    z = sims.qpos[slots, 2]
    healthy = (1.0 < z) & (z < 2.0)
    rewards = 1.25 * x_velocity + healthy * 5.0
    ctrl_cost = ctrl_cost_weight * np.sum(np.square(sims.ctrl[slots]), axis=-1)
    forces = sims.cfrc_ext[slots]
    contact_cost = np.clip(5e-7 * np.sum(np.square(forces).reshape(len(forces), -1), axis=-1), -np.inf, 10.0)
    return rewards - (ctrl_cost + contact_cost), healthy


def _no_position(model: mujoco.MjModel, sims: Any, slots: Slots) -> float:
    """The pendulums, Reacher and Pusher have no forward reward."""
    return 0.0


def _qpos_qvel(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """inverted_pendulum_v5's ``_get_obs``: qpos and qvel."""
    return [sims.qpos[slots], sims.qvel[slots]]


def _qpos_qvel_size(model: mujoco.MjModel) -> int:
    return model.nq + model.nv


def _pendulum_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """inverted_pendulum_v5: 1 a step while the observation is finite and the pole within 0.2 rad of upright
    (the episode ends when it is not)."""
    qpos, qvel = sims.qpos[slots], sims.qvel[slots]
    healthy = np.isfinite(qpos).all(axis=1) & np.isfinite(qvel).all(axis=1) & ~(np.abs(qpos[:, 1]) > 0.2)
    return healthy * 1.0, healthy


def _double_pendulum_obs(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """inverted_double_pendulum_v5's ``_get_obs``: the cart's position, the sines and cosines of the hinges,
    qvel and the cart's constraint force, each clipped to [-10, 10]."""
    qpos = sims.qpos[slots]
    return [
        qpos[:, :1],
        np.sin(qpos[:, 1:]),
        np.cos(qpos[:, 1:]),
        np.clip(sims.qvel[slots], -10, 10),
        np.clip(sims.qfrc_constraint[slots], -10, 10)[:, :1],
    ]


def _double_pendulum_size(model: mujoco.MjModel) -> int:
    return 1 + 2 * (model.nq - 1) + model.nv + 1


def _double_pendulum_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """inverted_double_pendulum_v5: 10 while the tip (site 0) is above y = 1, less its distance and velocity
    penalties; the episode ends when the tip falls to y <= 1."""
    tip = sims.site_xpos[slots, 0]
    x, y = tip[:, 0], tip[:, 2]
    v1, v2 = sims.qvel[slots, 1], sims.qvel[slots, 2]
    healthy = ~(y <= 1)
    dist_penalty = 0.01 * x**2 + (y - 2) ** 2
    vel_penalty = 0.001 * v1**2 + 0.005 * v2**2
    return 10.0 * healthy - dist_penalty - vel_penalty, healthy


def _body_com(model: mujoco.MjModel, sims: Any, slots: Slots, body: str) -> np.ndarray:
    """Gymnasium's ``get_body_com(body)``: the body's ``xpos``, rows [k, 3]."""
    return sims.xpos[slots, model.body(body).id]


def _norms(vec: np.ndarray) -> np.ndarray:
    """``np.linalg.norm`` of each row of ``vec`` [k, 3]: ``np.vecdot`` runs the dot product that ``norm`` runs on
    one vector (numpy's BLAS ddot), so each equals Gymnasium's bit for bit, where ``norm(axis=1)`` does not."""
    return np.sqrt(np.vecdot(vec, vec))


def _ctrl_reward(action: np.ndarray, weight: float) -> np.ndarray:
    """reacher_v5's and pusher_v5's ``reward_ctrl``: minus the float32 action's squares, weighted."""
    return -np.square(action).sum(axis=-1) * weight


def _never_ends(reward: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A reward with the healthy state of a task that never terminates (Reacher, Pusher)."""
    return reward, np.ones(len(reward), dtype=bool)


def _reacher_obs(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """reacher_v5's ``_get_obs``: the arm's cosines and sines, the target's position, the arm's velocities and
    the fingertip's offset from the target in the plane."""
    qpos = sims.qpos[slots]
    theta = qpos[:, :2]
    offset = _body_com(model, sims, slots, "fingertip") - _body_com(model, sims, slots, "target")
    return [np.cos(theta), np.sin(theta), qpos[:, 2:], sims.qvel[slots, :2], offset[:, :2]]


def _reacher_size(model: mujoco.MjModel) -> int:
    return 2 + 2 + (model.nq - 2) + 2 + 2


def _reacher_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """reacher_v5: minus the fingertip's distance to the target (weight 1) plus ``reward_ctrl``."""
    vec = _body_com(model, sims, slots, "fingertip") - _body_com(model, sims, slots, "target")
    reward_dist = -_norms(vec) * 1
    return _never_ends(reward_dist + _ctrl_reward(action, ctrl_cost_weight))


def _reacher_reset(model: mujoco.MjModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """reacher_v5's ``reset_model``: the arm's angles noised by U(-0.1, 0.1), a goal drawn in the disc of radius
    0.2, the arm's velocities by U(-0.005, 0.005) and the target's zero."""
    qpos = rng.uniform(low=-0.1, high=0.1, size=model.nq) + model.qpos0
    while True:
        goal = rng.uniform(low=-0.2, high=0.2, size=2)
        if np.linalg.norm(goal) < 0.2:
            break
    qpos[-2:] = goal
    qvel = np.zeros(model.nv) + rng.uniform(low=-0.005, high=0.005, size=model.nv)
    qvel[-2:] = 0
    return qpos, qvel


def _pusher_obs(model: mujoco.MjModel, sims: Any, slots: Slots) -> list[np.ndarray]:
    """pusher_v5's ``_get_obs``: the arm's 7 angles and velocities, the positions of its tip, the object and the
    goal."""
    coms = [_body_com(model, sims, slots, body) for body in ("tips_arm", "object", "goal")]
    return [sims.qpos[slots, :7], sims.qvel[slots, :7], *coms]


def _pusher_size(model: mujoco.MjModel) -> int:
    return 7 + 7 + 3 * 3


def _pusher_reward(
    model: mujoco.MjModel, sims: Any, slots: Slots, action: np.ndarray, x_velocity: np.ndarray, ctrl_cost_weight: float
) -> tuple[np.ndarray, np.ndarray]:
    """pusher_v5: minus the object's distance to the goal (weight 1), ``reward_ctrl``, minus the tip's distance
    to the object (weight 0.5), summed in that order."""
    obj = _body_com(model, sims, slots, "object")
    reward_near = -_norms(obj - _body_com(model, sims, slots, "tips_arm")) * 0.5
    reward_dist = -_norms(obj - _body_com(model, sims, slots, "goal")) * 1
    return _never_ends(reward_dist + _ctrl_reward(action, ctrl_cost_weight) + reward_near)


def _pusher_reset(model: mujoco.MjModel, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """pusher_v5's ``reset_model``: the arm at rest, the cylinder drawn in [-0.3, 0] x [-0.2, 0.2] farther than
    0.17 from the goal at the origin, the arm's velocities by U(-0.005, 0.005), the cylinder's and goal's zero."""
    qpos = model.qpos0.copy()
    goal = np.asarray([0, 0])
    while True:
        cylinder = np.concatenate([rng.uniform(low=-0.3, high=0, size=1), rng.uniform(low=-0.2, high=0.2, size=1)])
        if np.linalg.norm(cylinder - goal) > 0.17:
            break
    qpos[-4:-2] = cylinder
    qpos[-2:] = goal
    qvel = np.zeros(model.nv) + rng.uniform(low=-0.005, high=0.005, size=model.nv)
    qvel[-4:] = 0
    return qpos, qvel


HOPPER = Terms((), _qpos_x, _planar_obs, _hopper_reward, _planar_size)
WALKER2D = Terms((), _qpos_x, _planar_obs, _walker2d_reward, _planar_size)
ANT = Terms(("xpos", "cfrc_ext"), _torso_x, _ant_obs, _ant_reward, _ant_size)
HUMANOID = Terms(
    ("xipos", "cinert", "cvel", "qfrc_actuator", "cfrc_ext"), _mass_center_x, _humanoid_obs, _humanoid_reward, com_size
)
INVERTED_PENDULUM = Terms((), _no_position, _qpos_qvel, _pendulum_reward, _qpos_qvel_size)
INVERTED_DOUBLE_PENDULUM = Terms(
    ("site_xpos", "qfrc_constraint"), _no_position, _double_pendulum_obs, _double_pendulum_reward, _double_pendulum_size
)
REACHER = Terms(("xpos",), _no_position, _reacher_obs, _reacher_reward, _reacher_size, _reacher_reset)
PUSHER = Terms(("xpos",), _no_position, _pusher_obs, _pusher_reward, _pusher_size, _pusher_reset)
