"""The GA end to end on an early-terminating locomotion task: train.py on Hopper (mujoco_batch), a tiny budget."""

from __future__ import annotations

import pytest
from conftest import TINY, run_train

from spn_torchrl.records import read_progress


@pytest.mark.slow  # train.py in a subprocess
def test_ga_runs_on_hopper_and_counts_the_steps_its_episodes_ran(tmp_path):
    """Two generations of 10 on Hopper: each row's env steps are the steps the episodes ran before their healthy
    state ended them (fewer than the 1000-step limit allows), summed into the total."""
    run_train(tmp_path, "env=hopper", *TINY, "evaluator.processes=1", "torch_threads=1", "logger=csv")
    rows = read_progress(tmp_path / "progress.csv")
    assert [int(r["generation"]) for r in rows] == [1, 2]
    steps = [int(r["env_steps"]) for r in rows]
    most = 10 * 1000 + 2 * 5 * 1000  # the population and the elite re-evaluation, every episode at the time limit
    assert all(0 < s < most for s in steps)
    assert int(rows[-1]["total_env_steps"]) == sum(steps)
    assert all(float(r["eval_return"]) > 0 for r in rows)  # the healthy reward of 1 a step outweighs the costs
