"""Fixed genomes on two backends: their return distributions side by side, with Welch's test per genome.

``python -m spn_torchrl.tools.v2_compare --env HalfCheetah [--genomes 3] [--episodes 30]`` builds ``--genomes``
Connections-GA genomes (seeded fixed weights and scores, as a GA's generation 1 draws them), runs each for
``--episodes`` episodes on ``gym_v2`` (the v2 id) and on ``mujoco_batch_mj210`` and ``mujoco_batch`` (the v5 id),
and prints each genome's mean and sd per backend and Welch's p of each v5 backend against gym_v2. The episodes of
the backends start from different draws (Gym 0.21 and Gymnasium seed differently), so the test is of the
distributions, not of paired episodes.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence

import numpy as np
import torch

from spn_torchrl.analysis.stats import welch
from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import build_spn, init_fixed_weights

BACKEND_IDS = {"gym_v2": "{}-v2", "mujoco_batch_mj210": "{}-v5", "mujoco_batch": "{}-v5"}


def fixed_genome_returns(task: str, backend: str, genomes: int, episodes: int, seed: int = 0) -> np.ndarray:
    """Returns [genomes, episodes] of ``genomes`` seeded Connections genomes of ``task`` (e.g. "HalfCheetah")
    on ``backend``, episode e of each on env seed ``1000 * g + e``."""
    env_id = BACKEND_IDS[backend].format(task)
    spec = task_spec(env_id)
    generator = torch.Generator().manual_seed(seed)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, 64, generator)
    scores = torch.randn(genomes, w1.numel() + w2.numel(), generator=generator)
    spn = build_spn(
        w1, w2, genome_kind="connections", discrete=False, action_low=spec.action_low, action_high=spec.action_high
    )
    env = make_batched_env(env_id, episodes, backend=backend)
    try:
        evaluate = PopulationEvaluator(env, spn, spec.max_episode_steps)
        out = [evaluate(scores[g].expand(episodes, -1), 1000 * g).returns.numpy() for g in range(genomes)]
    finally:
        env.close()
    return np.stack(out)


def welch_p(a: np.ndarray, b: np.ndarray) -> float:
    """Welch's two-sided p of two samples of returns."""
    return welch(a.mean(), a.std(ddof=1), a.size, b.mean(), b.std(ddof=1), b.size).p


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m spn_torchrl.tools.v2_compare", description=__doc__.splitlines()[0])
    parser.add_argument("--env", default="HalfCheetah", choices=("HalfCheetah", "Swimmer"))
    parser.add_argument("--genomes", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    runs = {b: fixed_genome_returns(args.env, b, args.genomes, args.episodes, args.seed) for b in BACKEND_IDS}
    print(f"{args.env}: {args.genomes} fixed genomes x {args.episodes} episodes (mean +- sd; Welch's p vs gym_v2)")
    for g in range(args.genomes):
        cells = [f"{b} {r[g].mean():.1f} +- {r[g].std(ddof=1):.1f}" for b, r in runs.items()]
        ps = [f"p({b}) = {welch_p(runs['gym_v2'][g], runs[b][g]):.3g}" for b in BACKEND_IDS if b != "gym_v2"]
        print(f"  genome {g}: " + "; ".join(cells) + "; " + ", ".join(ps))


if __name__ == "__main__":
    main()
