"""A checkpoint that loads but does not hold what its format does (an entry missing, of another type or shape) is
refused by ``checkpoint.load`` in one sentence naming the file and the entry; every state the runs write passes."""

from __future__ import annotations

import pytest
import torch

from spn_torchrl import checkpoint
from spn_torchrl.errors import CheckpointError
from spn_torchrl.snn import observations

D = 6 * 3 + 2 * 6  # w1 [6, 3], w2 [2, 6]


def ga_state(ec: bool = False, normalised: bool = False, pending: bool = True) -> dict:
    """A GA/3 (or EC/1) state as evolve writes it, after 2 generations, the second's re-evaluation pending."""
    state = {
        "meta": {"format": checkpoint.EC_FORMAT if ec else checkpoint.GA_FORMAT, "env_id": "CartPole-v1"},
        "config": {"seed": 0},
        "run_name": "r",
        "wandb_id": None,
        "rows": [{"generation": 1}],
        "generation": 2,
        "population": torch.zeros(4, D),
        "pending": {
            "generation": 2,
            "population": torch.zeros(2, D),
            "fitness": torch.zeros(4),
            "steps": 10,
            "candidates": torch.zeros(2, dtype=torch.long),
        }
        if pending
        else None,
        "rng": torch.Generator().get_state(),
        "w1": torch.zeros(6, 3),
        "w2": torch.zeros(2, 6),
        "elites": torch.zeros(1, D),
        "total_env_steps": 20,
        "wall_time_s": 1.5,
    }
    if ec:
        state.update(p=torch.full((D,), 0.5), adam={"m": torch.zeros(D), "v": torch.zeros(D), "t": 2})
    if normalised:
        state.update(obs_stats=observations.initial_stats(3), elite_norms=torch.zeros(2, 1, 3))
    return state


def ppo_state() -> dict:
    return {
        "meta": {"format": checkpoint.PPO_FORMAT, "env_id": "CartPole-v1"},
        "config": {},
        "run_name": "r",
        "wandb_id": "abc",
        "rows": [],
        "iteration": 1,
        "actor": {"w": torch.zeros(2)},
        "critic": {},
        "optim": {},
        "counts": {},
        "wall_time_s": 0.5,
        "torch_rng": torch.get_rng_state(),
    }


def saved(tmp_path, state):
    path = tmp_path / checkpoint.CHECKPOINT_NAME
    torch.save(state, path)
    return path


@pytest.mark.parametrize(
    "state",
    [ga_state(), ga_state(pending=False), ga_state(ec=True), ga_state(ec=True, normalised=True), ppo_state()],
    ids=["ga", "ga-done", "ec", "ec-normalised", "ppo"],
)
def test_every_state_the_runs_write_loads(tmp_path, state):
    assert checkpoint.load(saved(tmp_path, state))["meta"] == state["meta"]


def damage(state: dict, key: str, value) -> dict:
    """``state`` with ``key`` (``a.b`` inside a dict entry) set to ``value`` (``...``: removed)."""
    state = {k: dict(v) if isinstance(v, dict) else v for k, v in state.items()}
    *outer, last = key.split(".")
    target = state[outer[0]] if outer else state
    if value is ...:
        del target[last]
    else:
        target[last] = value
    return state


GA_DAMAGES = [
    ("population", ..., "no 'population' entry"),
    ("w1", [[0.0]], "'w1' is a list, not a 2-dimensional tensor"),
    ("w1", torch.zeros(3), "'w1' is a shape (3,), not a 2-dimensional tensor"),
    ("w2", torch.zeros(2, 5), "'w1' (6, 3) and 'w2' (2, 5) are not [h, n] and [m, h]"),
    ("elites", torch.zeros(1, D + 1), f"'elites' has shape (1, {D + 1}), not {D} genes"),
    ("population", torch.zeros(4, 3), f"'population' has shape (4, 3), not {D} genes"),
    ("rng", torch.zeros(7, dtype=torch.uint8), "'rng' is not a random generator's state"),
    ("rng", torch.zeros(5056), "'rng' holds torch.float32, not torch.uint8"),
    ("generation", "2", "'generation' is a str"),
    ("rows", [1, 2], "'rows' holds a int, not a row"),
    ("config", 3, "'config' is a int"),
    ("pending.candidates", ..., "no 'pending.candidates' entry"),
    ("pending.population", torch.zeros(2, 4), f"'pending.population' has shape (2, 4), not {D} genes"),
    ("meta.env_id", ..., "no 'meta.env_id' entry"),
]


@pytest.mark.parametrize("key,value,problem", GA_DAMAGES, ids=[f"{k}-{p[:12]}" for k, _, p in GA_DAMAGES])
def test_a_damaged_ga_checkpoint_is_one_sentence_naming_the_entry(tmp_path, key, value, problem):
    path = saved(tmp_path, damage(ga_state(), key, value))
    with pytest.raises(CheckpointError) as err:
        checkpoint.load(path)
    assert str(err.value).startswith(f"{path} is a damaged {checkpoint.GA_FORMAT} checkpoint ({problem}")
    assert "\n" not in str(err.value)


@pytest.mark.parametrize(
    "key,value,problem",
    [
        ("p", torch.zeros(D - 1), f"'p' has shape ({D - 1},), not {D} genes"),
        ("adam.t", ..., "no 'adam.t' entry"),
        ("obs_stats.std", ..., "no 'obs_stats.std' entry"),
        ("elite_norms", torch.zeros(2, 3, 3), "'elite_norms' has shape (2, 3, 3), not [2, 1, n] beside 1 elites"),
    ],
)
def test_a_damaged_ec_checkpoint_is_one_sentence_naming_the_entry(tmp_path, key, value, problem):
    path = saved(tmp_path, damage(ga_state(ec=True, normalised=True), key, value))
    with pytest.raises(CheckpointError) as err:
        checkpoint.load(path)
    assert str(err.value).startswith(f"{path} is a damaged {checkpoint.EC_FORMAT} checkpoint ({problem}")


@pytest.mark.parametrize("key,value", [("actor", [1]), ("torch_rng", torch.zeros(3, dtype=torch.uint8))])
def test_a_damaged_ppo_checkpoint_is_one_sentence(tmp_path, key, value):
    path = saved(tmp_path, damage(ppo_state(), key, value))
    with pytest.raises(CheckpointError) as err:
        checkpoint.load(path)
    assert str(err.value).startswith(f"{path} is a damaged {checkpoint.PPO_FORMAT} checkpoint ('{key}'")


def test_a_meta_that_is_not_a_mapping_is_not_a_checkpoint(tmp_path):
    path = saved(tmp_path, {**ga_state(), "meta": "x"})
    with pytest.raises(CheckpointError, match="is not a spn_torchrl checkpoint"):
        checkpoint.load(path)
