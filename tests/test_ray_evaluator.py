import threading
import time

import numpy as np
import pytest
import torch
from conftest import compose_config

ray = pytest.importorskip("ray", reason="the Ray evaluator needs the ray extra: pip install -e '.[ray]'")

from spn_torchrl.config import to_run_config  # noqa: E402
from spn_torchrl.envs import make_transformed_env, task_spec  # noqa: E402
from spn_torchrl.errors import ConfigError, EvaluatorError  # noqa: E402
from spn_torchrl.evaluation import make_evaluator  # noqa: E402
from spn_torchrl.evaluation.rollout import PopulationEvaluator  # noqa: E402
from spn_torchrl.evaluation.shards import decode_genomes, encode_genomes, shard_bounds  # noqa: E402
from spn_torchrl.snn.policies import init_fixed_weights, spn_from_config  # noqa: E402
from spn_torchrl.training import ga  # noqa: E402


@pytest.fixture(scope="module")
def ray_cluster():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def make_cfg(*overrides):
    return to_run_config(
        compose_config("evaluator=ray", "algo.elite_candidates=1", "algo.elite_episodes=1", *overrides)
    )


def setup(cfg, sigma=1.0):
    spec = task_spec(cfg.env.id)
    generator = torch.Generator().manual_seed(cfg.seed)
    w1, w2 = init_fixed_weights(spec.n_obs, spec.n_act, cfg.algo.snn.hidden, generator)
    spn = spn_from_config(cfg.algo.snn, cfg.algo.genome, spec, w1, w2)
    genomes = ga.initial_population(cfg.algo.population, spn.genome_size, sigma, generator)
    return spec, spn, genomes


def local_episodes(cfg, spec, spn, genomes, seed):
    env = make_transformed_env(spec.env_id, cfg.algo.population, backend=cfg.env.backend)
    evaluator = PopulationEvaluator(env, spn, spec.max_episode_steps)
    try:
        return evaluator(genomes, seed)
    finally:
        evaluator.close()


def test_shards_cover_the_population_and_fit_the_actors():
    for population in (2, 7, 10, 200):
        for parts in range(1, population + 1, 3):
            full = shard_bounds(population, parts)
            assert full[0][0] == 0 and full[-1][1] == population
            assert all(a[1] == b[0] for a, b in zip(full, full[1:]))
            for count in range(1, population + 1):
                sub = shard_bounds(count, parts)
                assert sum(stop - start for start, stop in sub) == count
                assert all(s[1] - s[0] <= f[1] - f[0] for s, f in zip(sub, full))


@pytest.mark.parametrize("algo", ["conn_ga", "weights_ga"])
def test_encoded_genomes_give_the_same_effective_weights(algo):
    cfg = make_cfg(f"algo={algo}", "env=swimmer", "algo.population=6")
    _, spn, genomes = setup(cfg, sigma=1e-8 if algo == "conn_ga" else 1.0)  # tiny scores: sigmoid rounds to 0.5
    payload = encode_genomes(spn, genomes)
    if algo == "conn_ga":
        assert payload.dtype == np.uint8 and payload.shape == (6, -(-spn.genome_size // 8))
    else:
        assert payload.dtype == np.float32 and payload.shape == (6, spn.genome_size)
    a = spn.effective_weights(genomes)
    b = spn.effective_weights(decode_genomes(payload, spn.genome_kind, spn.genome_size))
    assert all(torch.equal(x, y) for x, y in zip(a, b))


@pytest.mark.slow
# 6 on 4 actors: uneven shards (2, 2, 1, 1), and 3 genomes leave one actor idle
@pytest.mark.parametrize(
    "algo,env,population,actors", [("conn_ga", "cartpole", 10, 2), ("weights_ga", "cartpole", 6, 4)]
)
def test_ray_gives_the_local_evaluators_episodes(ray_cluster, algo, env, population, actors):
    cpus = 2 / actors
    cfg = make_cfg(
        f"algo={algo}",
        f"env={env}",
        f"algo.population={population}",
        f"evaluator.num_actors={actors}",
        f"evaluator.num_cpus_per_actor={cpus}",
    )
    spec, spn, genomes = setup(cfg)
    evaluator = make_evaluator(cfg, spec, spn)
    try:
        remote = evaluator(genomes, 321)
        remote_part = evaluator(genomes[:3], 77)  # fewer genomes than the population
    finally:
        evaluator.close()
    local = local_episodes(cfg, spec, spn, genomes, 321)
    local_part = local_episodes(cfg, spec, spn, genomes[:3], 77)
    assert len(set(local.steps.tolist())) > 1  # distinct episodes, not one repeated
    for got, want in ((remote, local), (remote_part, local_part)):
        assert got.returns.dtype == want.returns.dtype and got.steps.dtype == want.steps.dtype
        assert torch.equal(got.returns, want.returns)
        assert torch.equal(got.steps, want.steps)
        assert torch.equal(got.spikes, want.spikes)
    assert evaluator.bytes_sent > 0 and evaluator.bytes_received == 16 * (population + 3)


def kill_during_call(evaluator, genomes, actor_index, no_restart, seed):
    """Evaluate while another thread kills one actor once the call is under way."""
    actor = evaluator.actors[actor_index]
    killed = threading.Event()

    def killer():
        time.sleep(0.3)
        ray.kill(actor, no_restart=no_restart)
        killed.set()

    thread = threading.Thread(target=killer)
    thread.start()
    try:
        return evaluator(genomes, seed), killed
    finally:
        thread.join()


def slow_setup(*overrides):
    """HalfCheetah episodes run their full 1000 steps: a call lasts long enough to kill an actor during it."""
    cfg = make_cfg("env=halfcheetah", "algo.population=40", "evaluator.num_actors=2", *overrides)
    spec, spn, genomes = setup(cfg)
    return cfg, spec, spn, genomes


@pytest.mark.slow
def test_an_actor_killed_mid_call_is_a_clear_error(ray_cluster):
    cfg, spec, spn, genomes = slow_setup("evaluator.max_restarts=0")
    evaluator = make_evaluator(cfg, spec, spn)
    started = time.monotonic()
    try:
        with pytest.raises(EvaluatorError, match=r"Ray actor 1 \(individuals 20..39\) died"):
            kill_during_call(evaluator, genomes, 1, no_restart=True, seed=5)
    finally:
        evaluator.close()
    assert time.monotonic() - started < 60  # an error, not a hang


@pytest.mark.slow
def test_an_actor_killed_mid_call_is_restarted_and_its_shard_rerun(ray_cluster):
    cfg, spec, spn, genomes = slow_setup("evaluator.max_restarts=1")
    evaluator = make_evaluator(cfg, spec, spn)
    try:
        episodes, killed = kill_during_call(evaluator, genomes, 0, no_restart=False, seed=5)
    finally:
        evaluator.close()
    assert killed.is_set()
    assert torch.equal(episodes.steps, torch.full((40,), 1000))
    assert torch.equal(episodes.returns, local_episodes(cfg, spec, spn, genomes, 5).returns)


@pytest.mark.slow
def test_too_many_actors_for_the_cluster_is_a_clear_error(ray_cluster):
    cfg = make_cfg(
        "algo.population=10", "evaluator.num_actors=3", "evaluator.num_cpus_per_actor=1", "evaluator.start_timeout_s=5"
    )
    spec, spn, _ = setup(cfg)
    with pytest.raises(EvaluatorError, match=r"[1-3] of 3 Ray actors did not start .*the cluster has 2 CPUs"):
        make_evaluator(cfg, spec, spn)


def test_bad_ray_settings_are_rejected():
    with pytest.raises(ConfigError, match="evaluator.num_actors"):
        make_cfg("algo.population=4", "evaluator.num_actors=5")
    with pytest.raises(ConfigError, match="evaluator.max_restarts"):
        make_cfg("evaluator.max_restarts=-1")


@pytest.mark.slow
def test_train_with_ray_logs_what_the_local_evaluator_logs(tmp_path):
    """The entry point end to end: a local Ray cluster started by the run, 2 actors, the same progress rows."""
    from conftest import TINY, run_train

    from spn_torchrl.records import read_progress

    timing = {"wall_time_s", "steps_per_s"}
    run_train(tmp_path / "local", "env=cartpole", *TINY)
    run_train(
        tmp_path / "ray", "env=cartpole", *TINY, "evaluator=ray", "evaluator.num_actors=2", "evaluator.num_cpus=2"
    )
    local, remote = (read_progress(tmp_path / name / "progress.csv") for name in ("local", "ray"))
    assert len(local) == len(remote) == 2
    for a, b in zip(local, remote):
        assert {k: v for k, v in a.items() if k not in timing} == {k: v for k, v in b.items() if k not in timing}
