"""Typed configs: every composition validates, the defaults are the paper's, and each bad value is one sentence."""

from pathlib import Path

import pytest
from conftest import CONF, compose_config
from omegaconf import OmegaConf

from spn_torchrl.config import ECConfig, GAConfig, LocalEvaluatorConfig, PPOConfig, RunConfig, SNNConfig, from_saved
from spn_torchrl.envs import BACKENDS
from spn_torchrl.errors import ConfigError
from spn_torchrl.run import check

ALGOS = sorted(p.stem for p in Path(CONF, "algo").glob("*.yaml"))
ENVS = sorted(p.stem for p in Path(CONF, "env").glob("*.yaml"))


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("env", ENVS)
def test_every_algo_and_env_composes_to_typed_objects(make_config, algo, env):
    cfg = make_config(f"algo={algo}", f"env={env}")
    schema = {"ga": GAConfig, "ec": ECConfig, "ppo": PPOConfig}[algo.rsplit("_", 1)[1]]
    assert isinstance(cfg, RunConfig) and isinstance(cfg.algo, schema)
    assert isinstance(cfg.algo.snn, SNNConfig) and isinstance(cfg.evaluator, LocalEvaluatorConfig)
    assert cfg.algo.name == algo and cfg.env.name == env
    check(cfg)


def test_defaults_are_the_papers_and_written_once(make_config):
    cfg = make_config()
    a = cfg.algo
    assert (a.generations, a.population, a.sigma, a.truncation) == (100, 200, 0.01, 0.25)
    assert (a.elite_candidates, a.elite_episodes, a.elitism, a.genome) == (10, 10, 0, "connections")
    assert a.snn == SNNConfig(hidden=64, time_steps=4, decay=0.75, v_threshold=0.5, score_threshold=0.5)
    assert make_config("algo=conn_ppo").algo.snn == a.snn == make_config("algo=weights_ga").algo.snn
    assert cfg.env.id == "CartPole-v1" and cfg.logger.backend == "csv"
    assert make_config("algo=weights_ga").algo.init_from_fixed_weights is False
    ppo = make_config("algo=dpn_ppo").algo
    assert (ppo.total_env_steps, ppo.epochs, ppo.minibatch_size, ppo.lr_policy, ppo.lr_value) == (
        1e6,
        25,
        100,
        1e-5,
        1e-4,
    )
    assert (ppo.gamma, ppo.gae_lambda, ppo.clip_epsilon, ppo.hidden) == (0.99, 0.95, 0.2, 64)


def test_yaml_files_list_only_what_differs_from_the_schema():
    schemas = {"ga_schema": GAConfig(), "ec_schema": ECConfig(), "ppo_schema": PPOConfig()}
    for path in Path(CONF, "algo").glob("*.yaml"):
        node = OmegaConf.load(path)
        schema = schemas[node.defaults[0]]
        for key, value in node.items():
            if key not in ("defaults", "name"):  # an option names itself
                assert getattr(schema, key) != value, f"{path.name}: {key}={value} is the schema's default"


def test_config_backend_names_are_the_registrys():
    from spn_torchrl.config import BACKENDS as NAMES

    assert set(NAMES) == set(BACKENDS)


# each rule, the override that breaks it, and the start of its sentence (issue 12's list first)
RULES = [
    (["algo=dpn_ppo", "evaluator=ray"], "evaluator must be local for algo=dpn_ppo"),
    (["algo.sigma=inf"], "algo.sigma must be a finite number in (0, inf), got inf"),
    (["algo.snn.v_threshold=nan"], "algo.snn.v_threshold must be a finite number"),
    (["algo=dpn_ppo", "algo.log_std_init=nan"], "algo.log_std_init must be a finite number in [-20, 2]"),
    (["algo=dpn_ppo", "algo.clip_epsilon=inf"], "algo.clip_epsilon must be a finite number in (0, inf)"),
    (["seed=-1"], "seed must be an integer in [0, 9223372036854775807], got -1"),
    (["algo.snn.hidden=99999999999999999999"], "algo.snn.hidden must be an integer in [1, 4096]"),
    (["algo.snn.time_steps=100000"], "algo.snn.time_steps must be an integer in [1, 64], got 100000"),
    (["env.backend=gymnasium", "env.threads=5"], "env.threads must be 1 for env.backend=gymnasium"),
    (["evaluator=ray", "evaluator.num_cpus=-3"], "evaluator.num_cpus must be an integer in [1, 100000], got -3"),
    (["+algo.foo=1"], "algo.foo is not a field of algo (GAConfig)"),
    (["+algo.snn.bar=1"], "algo.snn.bar is not a field of algo.snn (SNNConfig)"),
    (["algo.population=7"], "algo.population must be even"),
    (["algo.population=0"], "algo.population must be an integer in [2, 100000], got 0"),
    (["algo.truncation=0"], "algo.truncation must be a finite number in (0, 1]"),
    (["algo.truncation=1.5"], "algo.truncation must be a finite number in (0, 1]"),
    (["algo.sigma=0"], "algo.sigma must be a finite number in (0, inf)"),
    (["algo.snn.score_threshold=1"], "algo.snn.score_threshold must be a finite number in (0, 1)"),
    (["algo.generations=0"], "algo.generations must be an integer in [1, 100000]"),
    (["algo.elite_candidates=300"], "algo.elite_candidates must be an integer in [1, 200]"),
    (["algo.elite_episodes=0"], "algo.elite_episodes must be an integer in [1, 20]"),
    (["algo.elite_episodes=50"], "algo.elite_episodes must be an integer in [1, 20], got 50"),
    (["algo.genome=synapses"], "algo.genome must be one of 'connections', 'weights'"),
    (["algo.elitism=200"], "algo.elitism must be an integer in [0, 199]"),
    (["algo.init_from_fixed_weights=true"], "algo.init_from_fixed_weights must be false unless algo.genome=weights"),
    (["algo.snn.decay=2"], "algo.snn.decay must be a finite number in [0, 1]"),
    (["algo=dpn_ppo", "algo.policy=cnn"], "algo.policy must be one of 'dpn', 'spn'"),
    (["algo=dpn_ppo", "algo.total_env_steps=1500"], "algo.total_env_steps must be a multiple of algo.frames_per_batch"),
    (["algo=dpn_ppo", "algo.minibatch_size=300"], "algo.minibatch_size must be a divisor of algo.frames_per_batch"),
    (["algo=dpn_ppo", "algo.gamma=1.5"], "algo.gamma must be a finite number in [0, 1]"),
    (["algo=dpn_ppo", "algo.lr_policy=0"], "algo.lr_policy must be a finite number in (0, inf)"),
    (["algo=conn_ppo", "algo.surrogate=relu"], "algo.surrogate must be one of 'fast_sigmoid', 'atan'"),
    (["algo=conn_ppo", "algo.surrogate_alpha=-1"], "algo.surrogate_alpha must be a finite number in (0, inf)"),
    (["env.threads=0"], "env.threads must be an integer in [1, 256], got 0"),
    (["env.backend=warp"], "env.backend must be one of 'gymnasium', 'mujoco_batch', 'cartpole_batch'"),
    (["evaluator.processes=0"], "evaluator.processes must be an integer in [1, 256], got 0"),
    (["evaluator.start_timeout_s=0"], "evaluator.start_timeout_s must be a finite number in (0, inf)"),
    (["evaluator.call_timeout_s=nan"], "evaluator.call_timeout_s must be a finite number in (0, inf)"),
    (["evaluator=ray", "evaluator.num_actors=300"], "evaluator.num_actors must be an integer in [1, 200], got 300"),
    (["evaluator=ray", "evaluator.max_restarts=-1"], "evaluator.max_restarts must be an integer in [0, 100]"),
    (["logger.backend=tensorboard"], "logger.backend must be one of 'csv', 'wandb', 'none'"),
    (["logger.mode=maybe"], "logger.mode must be one of 'auto', 'online', 'offline', 'disabled'"),
    (["torch_threads=0"], "torch_threads must be an integer in [1, 256], got 0"),
    (["env.device=tpu"], "env.device must be cpu, cuda or cuda:<index>, got 'tpu'"),
    (["env.device=cuda"], "env.device must be cpu for env.backend=cartpole_batch"),
    (
        ["env=halfcheetah", "env.backend=mujoco_warp", "evaluator.processes=2"],
        "evaluator must be local with evaluator.processes 1 or null for env.backend=mujoco_warp",
    ),
    # algo=conn_ec (issue 46)
    (["algo=conn_ec", "algo.lr=0"], "algo.lr must be a finite number in (0, inf), got 0"),
    (["algo=conn_ec", "algo.eps=0.5"], "algo.eps must be a finite number in (0, 0.5), got 0.5"),
    (["algo=conn_ec", "algo.p_init=1"], "algo.p_init must be a finite number in [0.001, 0.999], got 1"),
    (["algo=conn_ec", "algo.adam_b1=1"], "algo.adam_b1 must be a finite number in [0, 1), got 1"),
    (["algo=conn_ec", "algo.adam_b2=nan"], "algo.adam_b2 must be a finite number in [0, 1)"),
    (["algo=conn_ec", "algo.adam_eps=0"], "algo.adam_eps must be a finite number in (0, inf), got 0"),
    (["algo=conn_ec", "algo.population=1"], "algo.population must be an integer in [2, 100000], got 1"),
    (["algo=conn_ec", "algo.generations=0"], "algo.generations must be an integer in [1, 100000], got 0"),
    (["algo=conn_ec", "algo.elite_episodes=0"], "algo.elite_episodes must be an integer in [1, 200], got 0"),
    (["algo=conn_ec", "+algo.sigma=0.1"], "algo.sigma is not a field of algo (ECConfig)"),
    (
        ["algo=conn_ec", "evaluator=ray", "evaluator.num_actors=201"],
        "evaluator.num_actors must be an integer in [1, 200]",
    ),
    # normalize_observations (issue 46)
    (
        ["normalize_observations=true", "env=swimmer", "env.backend=mujoco_warp"],
        "normalize_observations must be false for env.backend=mujoco_warp",
    ),
]


@pytest.mark.parametrize("overrides,sentence", RULES, ids=[" ".join(o) for o, _ in RULES])
def test_each_bad_value_is_one_sentence_naming_its_field(make_config, overrides, sentence):
    with pytest.raises(ConfigError) as err:
        make_config(*overrides)
    message = str(err.value)
    assert message.startswith(sentence) and "\n" not in message


@pytest.mark.parametrize(
    "overrides,sentence",
    [
        (["env.id=Nope-v0"], "env.id: unknown Gymnasium environment 'Nope-v0'"),
        (["env=cartpole", "env.backend=mujoco_batch"], "env.backend=mujoco_batch steps HalfCheetah-v5"),
        (["env=halfcheetah", "env.backend=cartpole_batch"], "env.backend=cartpole_batch steps CartPole-v1 only"),
        (["env=swimmer", "env.backend=mujoco_warp", "env.device=cuda:7"], "env.device=cuda:7: "),
    ],
)
def test_task_and_backend_are_checked_before_any_env_starts(make_config, overrides, sentence):
    with pytest.raises(ConfigError) as err:
        check(make_config(*overrides))
    assert str(err.value).startswith(sentence)


def test_a_wrong_type_or_an_unknown_key_without_plus_is_refused_by_hydra():
    from hydra.errors import ConfigCompositionException

    for override in ("algo.populaton=10", "algo.population=many"):
        with pytest.raises(ConfigCompositionException):
            compose_config(override)


def test_saved_configs_of_earlier_versions_load():
    old = {
        "algo": {
            "name": "conn_ga",
            "kind": "ga",
            "genome": "connections",
            "hidden": 32,
            "time_steps": 4,
            "decay": 0.75,
            "v_threshold": 0.5,
            "score_threshold": 0.5,
            "population": 20,
            "elite_candidates": 2,
            "elite_episodes": 2,
        },
        "env": {"name": "cartpole", "id": "CartPole-v1", "backend": "cartpole_batch", "num_workers": 1, "processes": 2},
        "logger": {"backend": "csv"},
        "evaluator": {"name": "local", "start_timeout_s": 300.0},
        "seed": 3,
    }
    cfg = from_saved(OmegaConf.to_yaml(OmegaConf.create(old)))
    assert cfg.algo.snn.hidden == 32 and cfg.env.threads == 1 and cfg.evaluator.processes == 2 and cfg.seed == 3


@pytest.mark.parametrize("preset", sorted(p.stem for p in Path(CONF, "experiment").glob("paper_*.yaml")))
def test_paper_presets_compose_for_every_swept_method(make_config, preset):
    params = OmegaConf.load(Path(CONF, "experiment", f"{preset}.yaml")).hydra.sweeper.params
    algos = str(params.algo).split(",")
    assert "conn_ga" in algos and str(params.seed) == "range(0,10)"
    for algo in algos:
        cfg = make_config(f"+experiment={preset}", f"algo={algo}")
        assert cfg.env.name == preset.removeprefix("paper_") and cfg.algo.name == algo
