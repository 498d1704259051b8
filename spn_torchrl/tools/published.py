"""Replay the authors' published generation-100 elites on today's tasks: the simulator's shift, as a number.

``python -m spn_torchrl.tools.published NPZ --env HalfCheetah-v5 [--episodes 10] [--seed 0]`` loads an
``<Env>_<Variant>_gen100_elites.npz`` (for each published seed S: ``seed_S`` the elite genome, scores for
SPN_Connections and weights for SPN_Weights, layer 1 [64, n] row-major then layer 2 [m, 64]; ``w1_seed_S``
[64, n] and ``w2_seed_S`` [m, 64] that run's fixed weights), runs every elite for ``--episodes`` episodes
with the project's SPN and evaluator (episode e of every elite uses env seed ``--seed + e``), and prints each
seed's mean return and the mean over seeds.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch

from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.envs.cartpole import ENV_ID as CARTPOLE_ID
from spn_torchrl.envs.gym_v2 import V2_TASKS
from spn_torchrl.envs.mujoco import BATCH_TASKS
from spn_torchrl.errors import SpnError
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import build_spn

SEED_KEY = re.compile(r"^seed_(\d+)$")


def genome_kind_of(path: str | Path) -> str:
    """``connections`` or ``weights`` from a published file's name (``..._SPN_Connections_...``)."""
    name = Path(path).name.lower()
    kinds = [kind for kind in ("connections", "weights") if kind in name]
    if len(kinds) != 1:
        raise SpnError(f"{path}: the file name must say Connections or Weights (or pass --genome-kind)")
    return kinds[0]


def default_backend(env_id: str) -> str:
    """The project's batched backend of a task: mujoco_batch for the MuJoCo v5 tasks, gym_v2 for the v2 ones,
    cartpole_batch for CartPole."""
    if env_id in V2_TASKS:
        return "gym_v2"
    if env_id in BATCH_TASKS:
        return "mujoco_batch"
    return "cartpole_batch" if env_id == CARTPOLE_ID else "gymnasium"


def load_published(path: str | Path) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """``{seed: (genome [D], w1 [h, n], w2 [m, h])}`` of a published elites file, by seed."""
    path = Path(path)
    if not path.is_file():
        raise SpnError(f"published elites file {path} does not exist")
    with np.load(path) as data:
        seeds = sorted(int(match.group(1)) for key in data.files if (match := SEED_KEY.match(key)))
        missing = [f"{kind}seed_{s}" for s in seeds for kind in ("w1_", "w2_") if f"{kind}seed_{s}" not in data.files]
        if not seeds or missing:
            raise SpnError(f"{path} must hold seed_S, w1_seed_S and w2_seed_S arrays (missing: {missing or 'seed_S'})")
        return {s: (data[f"seed_{s}"], data[f"w1_seed_{s}"], data[f"w2_seed_{s}"]) for s in seeds}


def replay(
    path: str | Path,
    env_id: str,
    episodes: int = 10,
    seed: int = 0,
    backend: str | None = None,
    genome_kind: str | None = None,
) -> dict[int, float]:
    """Mean return over ``episodes`` episodes (env seeds ``seed`` .. ``seed + episodes - 1``) of each published
    seed's elite on ``env_id``, by published seed."""
    if episodes < 1:
        raise SpnError(f"--episodes must be at least 1, got {episodes}")
    elites = load_published(path)
    kind = genome_kind or genome_kind_of(path)
    spec = task_spec(env_id)
    env = make_batched_env(env_id, episodes, backend=backend or default_backend(env_id))
    out: dict[int, float] = {}
    try:
        for s, (genome, w1, w2) in elites.items():
            if w1.shape[1] != spec.n_obs or w2.shape[0] != spec.n_act:
                raise SpnError(
                    f"{path}: seed {s} has weights [{w1.shape[0]}, {w1.shape[1]}] and [{w2.shape[0]}, {w2.shape[1]}], "
                    f"but {env_id} has n={spec.n_obs}, m={spec.n_act}"
                )
            spn = build_spn(
                torch.as_tensor(w1),
                torch.as_tensor(w2),
                genome_kind=kind,
                discrete=spec.discrete,
                action_low=spec.action_low,
                action_high=spec.action_high,
            )
            if genome.size != spn.genome_size:
                raise SpnError(f"{path}: seed {s} has a genome of {genome.size} genes, the SPN needs {spn.genome_size}")
            genomes = torch.as_tensor(genome, dtype=torch.float32).reshape(1, -1).expand(episodes, -1)
            out[s] = float(PopulationEvaluator(env, spn, spec.max_episode_steps)(genomes, seed).returns.mean())
    finally:
        if not env.is_closed:
            env.close()
    return out


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m spn_torchrl.tools.published", description=__doc__.splitlines()[0])
    parser.add_argument("npz", type=Path, help="an <Env>_<Variant>_gen100_elites.npz file")
    parser.add_argument("--env", required=True, help="Gymnasium task id to replay on, e.g. HalfCheetah-v5")
    parser.add_argument("--episodes", type=int, default=10, help="episodes per elite (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="env seed of the first episode (default 0)")
    parser.add_argument("--backend", default=None, help="env backend (default: mujoco_batch / cartpole_batch)")
    parser.add_argument(
        "--genome-kind", choices=("connections", "weights"), default=None, help="default: from the name"
    )
    args = parser.parse_args(argv)
    try:
        returns = replay(args.npz, args.env, args.episodes, args.seed, args.backend, args.genome_kind)
    except SpnError as err:
        sys.exit(f"error: {err}")
    values = np.array(list(returns.values()))
    print(f"{args.npz.name} on {args.env}, {args.episodes} episodes per elite (env seeds {args.seed}..):")
    for s, value in returns.items():
        print(f"  seed {s}: {value:.2f}")
    print(f"mean over {len(values)} seeds: {values.mean():.2f} (std {values.std():.2f})")


if __name__ == "__main__":
    main()
