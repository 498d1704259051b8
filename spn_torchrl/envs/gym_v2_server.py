"""Worker of ``env.backend=gym_v2``: K copies of a Gym 0.21 MuJoCo v2 task (mujoco-py on MuJoCo 2.1.0), stepped
on request over stdin/stdout.

Run by the gym_v2 venv's python as a script (``python gym_v2_server.py ENV_ID K``), so it imports numpy and gym
only, never the package. It first writes one JSON line: the task's sizes, action bounds and versions. Then it
answers requests, each a 1-byte op and a little-endian int32 count k, until stdin closes or op ``Q``:

- ``R`` + k int32 slots + k int64 seeds: reset those copies (seed >= 0: ``env.seed(seed)`` first, as Gym 0.21
  seeds an episode; -1: go on with the copy's generator); answers k x n_obs float64 observations.
- ``X`` + k int32 slots + k x (nq + nv) float64 states: ``env.set_state(qpos, qvel)`` of each (to start two
  simulators from one state); answers k x n_obs float64 observations.
- ``S`` + k int32 slots + k x n_act float32 actions: one ``env.step`` of each; answers k x n_obs float64
  observations, k float64 rewards and k uint8 termination flags.

The copies are ``gym.make(ENV_ID).unwrapped``: the client keeps the time limit.
"""

import json
import os
import sys

import numpy as np

HEADER = np.dtype("<i4")


def read_exact(stream, size):
    """``size`` bytes from ``stream``, or b"" at its end."""
    chunks, left = [], size
    while left:
        chunk = stream.read(left)
        if not chunk:
            return b""
        chunks.append(chunk)
        left -= len(chunk)
    return b"".join(chunks)


def versions():
    """The versions of the stack that steps the copies."""
    from importlib.metadata import version

    import gym
    import mujoco_py

    return {
        "gym": gym.__version__,
        "free_mujoco_py": version("free-mujoco-py"),
        "mujoco_py": mujoco_py.__version__,
        "mj_version": int(mujoco_py.functions.mj_version()),
        "numpy": np.__version__,
        "python": sys.version.split()[0],
    }


def serve(env_id, count, stdin, stdout):
    """Answer requests for ``count`` copies of ``env_id`` until stdin ends or op ``Q``."""
    import gym

    envs = [gym.make(env_id) for _ in range(count)]
    info = {
        "env_id": env_id,
        "n_obs": int(envs[0].observation_space.shape[0]),
        "n_act": int(envs[0].action_space.shape[0]),
        "action_low": envs[0].action_space.low.tolist(),
        "action_high": envs[0].action_space.high.tolist(),
        "max_episode_steps": envs[0].spec.max_episode_steps,
        "nq": int(envs[0].unwrapped.model.nq),
        "nv": int(envs[0].unwrapped.model.nv),
        **versions(),
    }
    raw = [env.unwrapped for env in envs]
    n_obs, n_act, nq, nv = info["n_obs"], info["n_act"], info["nq"], info["nv"]
    stdout.write((json.dumps(info) + "\n").encode())
    stdout.flush()
    while True:
        head = read_exact(stdin, 5)
        if not head or head[:1] == b"Q":
            return
        op, k = head[:1], int(np.frombuffer(head[1:], HEADER)[0])
        slots = np.frombuffer(read_exact(stdin, 4 * k), HEADER)
        if op == b"R":
            seeds = np.frombuffer(read_exact(stdin, 8 * k), "<i8")
            obs = np.empty((k, n_obs))
            for row, (slot, seed) in enumerate(zip(slots.tolist(), seeds.tolist())):
                if seed >= 0:
                    raw[slot].seed(seed)
                obs[row] = raw[slot].reset()
            stdout.write(obs.tobytes())
        elif op == b"X":
            states = np.frombuffer(read_exact(stdin, 8 * k * (nq + nv)), "<f8").reshape(k, nq + nv)
            obs = np.empty((k, n_obs))
            for row, slot in enumerate(slots.tolist()):
                raw[slot].set_state(states[row, :nq].copy(), states[row, nq:].copy())
                obs[row] = raw[slot]._get_obs()
            stdout.write(obs.tobytes())
        elif op == b"S":
            actions = np.frombuffer(read_exact(stdin, 4 * k * n_act), "<f4").reshape(k, n_act)
            obs, reward, done = np.empty((k, n_obs)), np.empty(k), np.zeros(k, dtype=np.uint8)
            for row, slot in enumerate(slots.tolist()):
                obs[row], reward[row], done[row], _ = raw[slot].step(actions[row])
            stdout.write(obs.tobytes() + reward.tobytes() + done.tobytes())
        else:
            raise SystemExit(f"gym_v2_server: unknown op {op!r}")
        stdout.flush()


if __name__ == "__main__":
    # the protocol keeps its own copy of stdout; anything gym or mujoco-py prints goes to stderr
    protocol = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)
    serve(sys.argv[1], int(sys.argv[2]), sys.stdin.buffer, protocol)
