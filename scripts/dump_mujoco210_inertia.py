"""Writes spn_torchrl/envs/data/mujoco210_inertia.json: MuJoCo 2.1.0's compiled body_mass, body_inertia, body_ipos
and body_iquat of HalfCheetah-v2 and Swimmer-v2, with their provenance (env.backend=mujoco_batch_mj210 reads it).

Run by the gym_v2 venv's python (``bash scripts/make_gym_v2_env.sh`` creates it):
``.venv-gym-v2/bin/python scripts/dump_mujoco210_inertia.py [OUT]``.
"""

import datetime
import hashlib
import json
import os
import sys

import gym
import numpy as np

# the worker's stack report (numpy and gym only, like this script; the package itself needs torch)
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "spn_torchrl", "envs"))
import gym_v2_server  # noqa: E402

TASKS = {"HalfCheetah-v2": "half_cheetah.xml", "Swimmer-v2": "swimmer.xml"}
FIELDS = ("body_mass", "body_inertia", "body_ipos", "body_iquat")
OUT = os.path.join(os.path.dirname(__file__), "..", "spn_torchrl", "envs", "data", "mujoco210_inertia.json")


def task_record(env_id, xml):
    model = gym.make(env_id).unwrapped.model
    path = os.path.join(os.path.dirname(gym.envs.mujoco.__file__), "assets", xml)
    with open(path, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()
    record = {"xml": xml, "xml_sha256": digest, "body_names": list(model.body_names)}
    for field in FIELDS:
        record[field] = np.asarray(getattr(model, field), dtype=np.float64).tolist()  # floats print round-trip
    return record


def main(out):
    data = {
        "provenance": {
            **gym_v2_server.versions(),
            "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "script": "scripts/dump_mujoco210_inertia.py",
        },
        "tasks": {env_id: task_record(env_id, xml) for env_id, xml in TASKS.items()},
    }
    with open(out + ".tmp", "w") as f:
        json.dump(data, f, indent=1)
        f.write("\n")
    os.replace(out + ".tmp", out)
    print(f"wrote {os.path.normpath(out)}")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else OUT)
