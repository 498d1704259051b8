"""Replaying published elites: a tiny synthetic npz in the authors' layout (never the reference files)."""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch

from spn_torchrl.envs import make_batched_env, task_spec
from spn_torchrl.errors import SpnError
from spn_torchrl.evaluation.rollout import PopulationEvaluator
from spn_torchrl.snn.policies import build_spn, init_fixed_weights
from spn_torchrl.tools.published import genome_kind_of, load_published, replay

ROOT = Path(__file__).resolve().parents[1]
N, M, H = 4, 2, 64  # CartPole-v1


def write_npz(path: Path, seeds=(10, 20), kind: str = "connections") -> dict[int, tuple]:
    """Random fixed weights and genomes per seed, as ``seed_S``, ``w1_seed_S``, ``w2_seed_S``."""
    arrays, out = {}, {}
    for s in seeds:
        w1, w2 = init_fixed_weights(N, M, H, torch.Generator().manual_seed(s))
        genome = torch.randn(H * N + M * H, generator=torch.Generator().manual_seed(s + 1))
        genome = genome if kind == "connections" else torch.cat([w1.flatten(), w2.flatten()]) * genome.sign()
        arrays |= {f"seed_{s}": genome.numpy(), f"w1_seed_{s}": w1.numpy(), f"w2_seed_{s}": w2.numpy()}
        out[s] = (genome, w1, w2)
    np.savez(path, **arrays)
    return out


def direct(genome, w1, w2, kind, episodes, seed) -> float:
    spec = task_spec("CartPole-v1")
    spn = build_spn(w1, w2, genome_kind=kind, discrete=True)
    env = make_batched_env("CartPole-v1", episodes, backend="cartpole_batch")
    try:
        episodes_out = PopulationEvaluator(env, spn, spec.max_episode_steps)(genome[None].expand(episodes, -1), seed)
    finally:
        env.close()
    return float(episodes_out.returns.mean())


@pytest.mark.parametrize("kind", ["connections", "weights"])
def test_replay_is_the_projects_evaluator_on_each_seeds_elite(tmp_path, kind):
    path = tmp_path / f"CartPole-v1_SPN_{kind.title()}_gen100_elites.npz"
    elites = write_npz(path, kind=kind)
    returns = replay(path, "CartPole-v1", episodes=3, seed=7)
    assert list(returns) == [10, 20]
    for s, (genome, w1, w2) in elites.items():
        assert returns[s] == pytest.approx(direct(genome, w1, w2, kind, 3, 7))


def test_genome_kind_from_the_file_name():
    assert genome_kind_of("HalfCheetah-v2_SPN_Connections_gen100_elites.npz") == "connections"
    assert genome_kind_of("/x/Swimmer-v2_SPN_Weights_gen100_elites.npz") == "weights"
    with pytest.raises(SpnError, match="Connections or Weights"):
        genome_kind_of("elites.npz")


def test_unusable_files_are_clear_errors(tmp_path):
    with pytest.raises(SpnError, match="does not exist"):
        load_published(tmp_path / "missing.npz")
    np.savez(tmp_path / "x_Connections.npz", seed_1=np.zeros(3))
    with pytest.raises(SpnError, match="must hold seed_S, w1_seed_S and w2_seed_S"):
        load_published(tmp_path / "x_Connections.npz")
    path = tmp_path / "CartPole_SPN_Connections.npz"
    write_npz(path, seeds=(1,))
    with pytest.raises(SpnError, match="Swimmer-v5 has n=8, m=2"):
        replay(path, "Swimmer-v5", episodes=1)


@pytest.mark.slow  # processes or a CLI in a subprocess
def test_cli_prints_each_seed_and_the_mean(tmp_path):
    path = tmp_path / "CartPole-v1_SPN_Connections_gen100_elites.npz"
    write_npz(path)
    cmd = [sys.executable, "-m", "spn_torchrl.tools.published", str(path), "--env", "CartPole-v1", "--episodes", "2"]
    proc = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.strip().splitlines()
    assert lines[1].startswith("  seed 10: ") and lines[2].startswith("  seed 20: ")
    values = [float(line.split(": ")[1]) for line in lines[1:3]]
    assert lines[3].startswith(f"mean over 2 seeds: {np.mean(values):.2f}")
    missing = subprocess.run(
        [*cmd[:3], str(tmp_path / "nope_Weights.npz"), *cmd[4:]], cwd=ROOT, capture_output=True, text=True
    )
    assert missing.returncode != 0 and missing.stderr.strip().startswith("error: published elites file")
