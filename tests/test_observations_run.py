"""normalize_observations end to end: train.py runs of the GA and EC with it on resume to the uninterrupted rows
and statistics; PPO's resume too; play replays and export writes each elite with its statistics."""

from __future__ import annotations

import pytest
import torch
from conftest import run_train, sigterm_after_first_checkpoint

from spn_torchrl import checkpoint
from spn_torchrl.records import read_progress
from spn_torchrl.seeds import REEVALUATION, episode_seed
from spn_torchrl.snn.observations import policy_norm
from spn_torchrl.tools.elite import load_elite
from spn_torchrl.tools.play import replay

pytestmark = pytest.mark.slow  # end-to-end runs

ON = ["env=cartpole", "algo.population=20", "algo.elite_episodes=2", "seed=2", "normalize_observations=true"]
METHODS = {"conn_ga": ["algo=conn_ga", "algo.elite_candidates=2"], "conn_ec": ["algo=conn_ec"]}
TIMING = {"wall_time_s", "steps_per_s"}


def rows(run_dir) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in TIMING} for r in read_progress(run_dir / "progress.csv")]


def same_statistics(a, b) -> bool:
    sa, sb = checkpoint.load(a), checkpoint.load(b)
    stats = sa["obs_stats"]["count"] == sb["obs_stats"]["count"] and all(
        torch.equal(sa["obs_stats"][k], sb["obs_stats"][k]) for k in ("mean", "summed_variance", "std")
    )
    return stats and torch.equal(sa["elite_norms"], sb["elite_norms"])


@pytest.fixture(scope="module", params=sorted(METHODS))
def four(request, tmp_path_factory):
    """An uninterrupted 4-generation run with normalised observations (GA, EC)."""
    run_dir = tmp_path_factory.mktemp(request.param) / "four"
    run_train(run_dir, *ON, *METHODS[request.param], "algo.generations=4")
    return request.param, run_dir


def test_a_run_keeps_its_statistics_and_each_elites_normalisation(four):
    _, run_dir = four
    state = checkpoint.load(run_dir)
    stats, norms = state["obs_stats"], state["elite_norms"]
    assert 0 < stats["count"] < read_progress(run_dir / "progress.csv")[-1]["total_env_steps"]  # fitness episodes only
    assert norms.shape == (2, 4, 4)  # (mean, inv_std) x generations x CartPole's 4 observations
    assert not norms[0, 0].any() and (norms[1, 0] == 1).all()  # generation 1 ran before any statistics
    assert all(not torch.equal(norms[0, g], norms[0, g + 1]) for g in range(3))
    # the last elite used its generation's statistics, not those updated after it
    assert not torch.equal(norms[0, 3], policy_norm(stats)[0])


def test_a_resumed_run_on_two_processes_gives_the_uninterrupted_rows_and_statistics(four, tmp_path):
    method, full = four
    if method == "conn_ga":  # stopped by SIGTERM with a pending re-evaluation in its checkpoint
        returncode, err = sigterm_after_first_checkpoint(tmp_path, *ON, *METHODS[method], "algo.generations=4")
        assert returncode == 143 and b"holds a consistent checkpoint" in err, err
        assert checkpoint.load(tmp_path)["pending"] is not None
    else:  # a finished shorter run, extended
        run_train(tmp_path, *ON, *METHODS[method], "algo.generations=2")
    run_train(tmp_path, *ON, *METHODS[method], "algo.generations=4", "resume=true", "evaluator.processes=2")
    assert rows(tmp_path) == rows(full)
    assert same_statistics(tmp_path, full)


def test_play_replays_the_elite_with_its_statistics(four):
    """The elite's re-evaluation episodes, replayed by play with the statistics it kept, give the logged return
    (the elite is candidate c of k, its episodes seeded base + c x E + j)."""
    _, run_dir = four
    elite = load_elite(run_dir)
    algo, last = elite.cfg.algo, read_progress(run_dir / "progress.csv")[-1]
    base = episode_seed(2, elite.generation, REEVALUATION)
    means = [
        float(replay(elite, algo.elite_episodes, base + c * algo.elite_episodes).returns.mean())
        for c in range(algo.elite_candidates)
    ]
    assert last["eval_return"] in means
    assert torch.equal(elite.obs_norm[0][0], elite.state["elite_norms"][0, -1])
    assert torch.equal(elite.obs_norm[1][0], elite.state["elite_norms"][1, -1])
