"""PPO: the trainable SPN, the loss, the run contract (progress, checkpoint, resume, eval) and a real run."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import torch
from conftest import compose_config

from spn_torchrl import ConfigError, run
from spn_torchrl.config import to_run_config
from spn_torchrl.envs import make_transformed_env, task_spec
from spn_torchrl.records import read_progress
from spn_torchrl.seeds import episode_seed
from spn_torchrl.snn.policies import PopulationSPN, TrainableSPN, init_fixed_weights
from spn_torchrl.snn.surrogate import surrogate_spike
from spn_torchrl.training.ppo import Keyed, evaluate_policy, load_actor, make_actor, make_critic

ROOT = Path(__file__).resolve().parents[1]

TINY = [
    "algo.total_env_steps=400",
    "algo.frames_per_batch=200",
    "algo.minibatch_size=50",
    "algo.epochs=2",
    "algo.eval_interval=1",
    "algo.eval_episodes=2",
    "logger=csv",
]


def make_cfg(*overrides: str):
    return to_run_config(compose_config(*overrides))


def _spns(discrete: bool, seed: int = 0):
    g = torch.Generator().manual_seed(seed)
    w1, w2 = init_fixed_weights(5, 3, 16, g)
    kwargs = dict(discrete=discrete, action_low=-torch.ones(3) * 0.7, action_high=torch.ones(3) * 0.7)
    pop = PopulationSPN(w1, w2, **kwargs)
    scores = torch.randn(pop.genome_size, generator=g)
    return pop, scores


@pytest.mark.parametrize("discrete", [False, True])
@pytest.mark.parametrize("surrogate", ["fast_sigmoid", "atan"])
def test_trainable_spn_forward_equals_population_spn(discrete: bool, surrogate: str) -> None:
    pop, scores = _spns(discrete)
    obs = 3.0 * torch.randn(32, 5, generator=torch.Generator().manual_seed(1))
    pop.set_genomes(scores.expand(32, -1))
    action, _ = pop(obs)
    out = TrainableSPN(pop, scores, surrogate_spike(surrogate))(obs)
    if discrete:
        assert torch.equal(out.argmax(-1), action)
    else:
        assert torch.equal(out, action)


@pytest.mark.parametrize("surrogate", ["fast_sigmoid", "atan"])
def test_gradients_reach_both_layers_scores(surrogate: str) -> None:
    pop, scores = _spns(discrete=True)
    spn = TrainableSPN(pop, scores, surrogate_spike(surrogate))
    obs = 3.0 * torch.randn(64, 5, generator=torch.Generator().manual_seed(2))
    spn(obs).square().sum().backward()
    grad = spn.scores.grad
    h, n = pop.w1.shape
    assert torch.isfinite(grad).all()
    # layer-1 scores only get a gradient through the spikes, i.e. through the surrogate derivative
    assert grad[: h * n].abs().sum() > 0
    assert grad[h * n :].abs().sum() > 0


def test_ppo_loss_decreases_on_a_fixed_batch() -> None:
    from torchrl.collectors import Collector
    from torchrl.objectives import ClipPPOLoss
    from torchrl.objectives.value import GAE

    torch.manual_seed(0)
    cfg = make_cfg("algo=dpn_ppo", "env=cartpole")
    spec = task_spec(cfg.env.id)
    env = make_transformed_env(spec.env_id, 1)
    actor, critic = make_actor(cfg, spec, env), make_critic(spec, 64)
    collector = Collector(env, actor, frames_per_batch=200, total_frames=200, auto_register_policy_transforms=False)
    data = next(iter(collector)).reshape(-1)
    collector.shutdown()
    with torch.no_grad():
        data = GAE(gamma=0.99, lmbda=0.95, value_network=critic)(data)
    loss_module = ClipPPOLoss(actor, critic, entropy_bonus=False, loss_critic_type="l2", functional=False)
    optim = torch.optim.Adam(list(actor.parameters()) + list(critic.parameters()), lr=1e-2)
    losses = []
    for _ in range(40):
        loss = loss_module(data)
        total = loss["loss_objective"] + loss["loss_critic"]
        losses.append(float(total))
        optim.zero_grad()
        total.backward()
        optim.step()
    assert losses[-1] < 0.5 * losses[0]


@pytest.mark.parametrize("out_keys", [["value"], ["loc", "scale"]])
def test_keyed_writes_what_a_tensordict_module_writes(out_keys: list[str]) -> None:
    from tensordict import TensorDict
    from tensordict.nn import AddStateIndependentNormalScale, TensorDictModule

    torch.manual_seed(0)
    net = torch.nn.Linear(4, 2) if len(out_keys) == 1 else AddStateIndependentNormalScale(4, init_value=-0.5)
    td = TensorDict({"observation": torch.randn(8, 4)}, batch_size=[8])
    ours = Keyed(net, in_keys=["observation"], out_keys=out_keys)(td.clone())
    theirs = TensorDictModule(net, in_keys=["observation"], out_keys=out_keys)(td.clone())
    assert set(ours.keys()) == set(theirs.keys()) == {"observation", *out_keys}
    assert all(torch.equal(ours[key], theirs[key]) for key in out_keys)
    assert list(Keyed(net, ["observation"], out_keys).state_dict()) == list(
        TensorDictModule(net, in_keys=["observation"], out_keys=out_keys).state_dict()
    )
    with pytest.raises(ValueError):
        Keyed(net, in_keys=["observation"], out_keys=["a", "b", "c"])(td.clone())


def _strip_time(rows):
    """Rows without timings, as text (NaN == NaN)."""
    return [{k: repr(v) for k, v in r.items() if k not in ("wall_time_s", "steps_per_s")} for r in rows]


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["dpn_ppo", "conn_ppo"])
def test_resume_replays_the_uninterrupted_run(tmp_path: Path, algo: str) -> None:
    full = run(make_cfg(f"algo={algo}", *TINY), tmp_path / "full")
    run(make_cfg(f"algo={algo}", *TINY, "algo.total_env_steps=200"), tmp_path / "cut")
    with pytest.raises(ConfigError, match="resume=true"):
        run(make_cfg(f"algo={algo}", *TINY), tmp_path / "cut")
    resumed = run(make_cfg(f"algo={algo}", *TINY, "resume=true"), tmp_path / "cut")
    assert resumed["iteration"] == full["iteration"] == 2
    rows_full = _strip_time(read_progress(tmp_path / "full" / "progress.csv"))
    rows_cut = _strip_time(read_progress(tmp_path / "cut" / "progress.csv"))
    assert rows_full == rows_cut
    assert rows_full[-1]["policy_forward"] == repr(2 * (200 + 2 * 200))
    assert rows_full[-1]["policy_backward"] == repr(2 * 2 * 200)
    a = torch.load(tmp_path / "full" / "checkpoint.pt", weights_only=True)["actor"]
    b = torch.load(tmp_path / "cut" / "checkpoint.pt", weights_only=True)["actor"]
    assert all(torch.equal(a[k], b[k]) for k in a)


@pytest.mark.slow
def test_resume_refuses_another_task(tmp_path: Path) -> None:
    run(make_cfg("algo=dpn_ppo", *TINY, "algo.total_env_steps=200"), tmp_path)
    from spn_torchrl import CheckpointError

    with pytest.raises(CheckpointError, match="policy"):
        run(make_cfg("algo=conn_ppo", *TINY, "resume=true"), tmp_path)


@pytest.mark.slow
def test_deterministic_eval_from_checkpoint_matches_the_logged_return(tmp_path: Path) -> None:
    cfg = make_cfg("algo=dpn_ppo", "env=swimmer", *TINY, "algo.total_env_steps=200", "algo.eval_episodes=2")
    row = run(cfg, tmp_path)
    actor, spec = load_actor(tmp_path, cfg)
    env = make_transformed_env(spec.env_id, 2)
    try:
        seed = episode_seed(cfg.seed, row["iteration"], 1)
        first, _ = evaluate_policy(actor, env, spec.max_episode_steps, seed)
        second, _ = evaluate_policy(actor, env, spec.max_episode_steps, seed)
    finally:
        env.close()
    assert torch.equal(first, second)
    assert float(first.mean()) == pytest.approx(row["eval_return"], rel=1e-6)


@pytest.mark.slow
def test_dpn_ppo_improves_cartpole_through_train_py(tmp_path: Path) -> None:
    """A real run of the entry point: 6 iterations of 1000 steps with a higher learning rate (~30 s)."""
    cmd = [
        sys.executable,
        str(ROOT / "train.py"),
        "algo=dpn_ppo",
        "env=cartpole",
        "seed=0",
        "algo.total_env_steps=6000",
        "algo.epochs=5",
        "algo.lr_policy=3e-3",
        "algo.lr_value=3e-3",
        "algo.eval_interval=3",
        f"hydra.run.dir={tmp_path}",
    ]
    subprocess.run(cmd, check=True, cwd=tmp_path, capture_output=True, timeout=120)
    rows = read_progress(tmp_path / "progress.csv")
    assert [r["iteration"] for r in rows] == list(range(1, 7))
    assert rows[-1]["eval_return"] >= 3 * rows[0]["train_return"]
    assert rows[-1]["eval_return"] >= 60
