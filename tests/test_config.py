from pathlib import Path

import pytest
from hydra import compose, initialize_config_dir
from hydra.errors import ConfigCompositionException
from omegaconf.errors import ConfigAttributeError, ValidationError

from spn_torchrl.config import register_configs, validate
from spn_torchrl.errors import ConfigError

CONF = str(Path(__file__).resolve().parents[1] / "conf")
ALGOS = sorted(p.stem for p in Path(CONF, "algo").glob("*.yaml"))
ENVS = sorted(p.stem for p in Path(CONF, "env").glob("*.yaml"))
register_configs()


def make(*overrides):
    with initialize_config_dir(config_dir=CONF, version_base=None):
        return compose(config_name="config", overrides=list(overrides))


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("env", ENVS)
def test_every_algo_and_env_composes_and_validates(algo, env):
    cfg = make(f"algo={algo}", f"env={env}")
    assert cfg.algo.name == algo and cfg.env.name == env
    validate(cfg)


def test_defaults_are_the_papers():
    cfg = make()
    a = cfg.algo
    assert (a.generations, a.population, a.sigma, a.truncation, a.score_threshold) == (100, 200, 0.01, 0.25, 0.5)
    assert (a.elite_candidates, a.elite_episodes, a.hidden, a.time_steps, a.decay, a.v_threshold) == (
        10,
        10,
        64,
        4,
        0.75,
        0.5,
    )
    assert a.elitism == 0 and cfg.env.id == "CartPole-v1" and cfg.logger.backend == "csv"
    assert make("algo=weights_ga").algo.init_from_fixed_weights is False


@pytest.mark.parametrize(
    "override,field",
    [
        ("algo.population=7", "algo.population"),
        ("algo.population=0", "algo.population"),
        ("algo.truncation=0", "algo.truncation"),
        ("algo.truncation=1.5", "algo.truncation"),
        ("algo.sigma=0", "algo.sigma"),
        ("algo.score_threshold=1", "algo.score_threshold"),
        ("algo.generations=0", "algo.generations"),
        ("algo.elite_candidates=300", "algo.elite_candidates"),
        ("algo.elite_episodes=0", "algo.elite_episodes"),
        ("algo.elite_episodes=50", "algo.elite_candidates * algo.elite_episodes"),
        ("algo.genome=synapses", "algo.genome"),
        ("algo.elitism=200", "algo.elitism"),
        ("algo.init_from_fixed_weights=true", "algo.init_from_fixed_weights"),
        ("algo.decay=2", "algo.decay"),
        ("env.num_workers=0", "env.num_workers"),
        ("env.processes=0", "env.processes"),
        ("env.processes=300", "env.processes"),
        ("evaluator.start_timeout_s=0", "evaluator.start_timeout_s"),
        ("env.backend=warp", "env.backend"),
        ("logger.backend=tensorboard", "logger.backend"),
        ("logger.mode=maybe", "logger.mode"),
        ("torch_threads=0", "torch_threads"),
    ],
)
def test_each_bad_value_names_its_field(override, field):
    with pytest.raises(ConfigError) as err:
        validate(make(override))
    message = str(err.value)
    assert message.startswith(field) and "\n" not in message


def test_wrong_type_and_unknown_key_are_rejected_by_the_schema():
    with pytest.raises(ConfigCompositionException) as err:
        make("algo.population=many")
    assert isinstance(err.value.__cause__, ValidationError) and "algo.population" in str(err.value.__cause__)
    with pytest.raises(ConfigCompositionException) as err:
        make("algo.populaton=10")
    assert isinstance(err.value.__cause__, ConfigAttributeError) and "populaton" in str(err.value.__cause__)


@pytest.mark.parametrize("preset", sorted(p.stem for p in Path(CONF, "experiment").glob("paper_*.yaml")))
def test_paper_presets_compose_for_every_swept_method(preset):
    from omegaconf import OmegaConf

    params = OmegaConf.load(Path(CONF, "experiment", f"{preset}.yaml")).hydra.sweeper.params
    algos = str(params.algo).split(",")
    assert "conn_ga" in algos and str(params.seed) == "range(0,10)"
    for algo in algos:
        cfg = make(f"+experiment={preset}", f"algo={algo}")
        assert cfg.env.name == preset.removeprefix("paper_") and cfg.algo.name == algo
        validate(cfg)
