"""Typed configs (Hydra structured configs) and the validation every run does before building an env.

Defaults are the paper's (SPEC.md); options that change the algorithm are off by default.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig

from spn_torchrl.errors import ConfigError


@dataclass
class GAConfig:
    """Connections-GA / Weights-GA (SPEC.md: G=100, N=200, sigma=0.01, eta=0.25, s_th=0.5)."""

    name: str = "conn_ga"
    kind: str = "ga"
    genome: str = "connections"  # "connections" (scores, masked fixed weights) or "weights"
    generations: int = 100
    population: int = 200
    sigma: float = 0.01
    truncation: float = 0.25
    score_threshold: float = 0.5
    elite_candidates: int = 10
    elite_episodes: int = 10
    hidden: int = 64
    time_steps: int = 4
    decay: float = 0.75
    v_threshold: float = 0.5
    elitism: int = 0  # option: keep the k best unchanged (the paper keeps none)
    init_from_fixed_weights: bool = False  # option (Weights-GA): start around the Kaiming weights, not 0


@dataclass
class PPOConfig:
    """DPN-PPO / Connections-PPO (SPEC.md, paper appendix): 1e6 steps as 1e3 iterations of 1e3 steps,
    25 epochs of minibatches of 100, Adam 1e-5 (policy) / 1e-4 (value), gamma 0.99, lambda 0.95, clip 0.2."""

    name: str = "dpn_ppo"
    kind: str = "ppo"
    policy: str = "dpn"  # "dpn" (n -> hidden ReLU -> m Tanh) or "spn" (the GA's SPN, its scores trained)
    total_env_steps: int = 1_000_000
    frames_per_batch: int = 1000  # env steps per iteration
    epochs: int = 25
    minibatch_size: int = 100
    lr_policy: float = 1e-5
    lr_value: float = 1e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip_epsilon: float = 0.2
    normalize_advantage: bool = True  # Spinning Up normalises advantages per batch
    hidden: int = 64
    log_std_init: float = -0.5  # Spinning Up's initial log-std of the Gaussian
    eval_interval: int = 10  # iterations between deterministic evaluations (the last one is always evaluated)
    eval_episodes: int = 10
    # Connections-PPO (policy=spn): the GA's SPN and its scores' initial spread
    surrogate: str = "fast_sigmoid"  # spike derivative: "fast_sigmoid" or "atan"
    surrogate_alpha: float = 2.0
    score_init_std: float = 0.01
    score_threshold: float = 0.5
    time_steps: int = 4
    decay: float = 0.75
    v_threshold: float = 0.5


@dataclass
class EnvConfig:
    name: str = MISSING
    id: str = MISSING
    backend: str = "gymnasium"
    num_workers: int = 1  # mujoco_batch: physics threads of each env; gymnasium: worker processes (ParallelEnv)
    processes: int = 1  # GA evaluation on this machine: processes that each run a shard of the population


@dataclass
class LocalEvaluatorConfig:
    """Evaluate the population on this machine, on envs of ``env.backend``."""

    name: str = "local"
    start_timeout_s: float = 300.0  # the worker processes of env.processes > 1 must be up (envs built) within this time


@dataclass
class RayEvaluatorConfig:
    """Shard the population across Ray actors, each stepping its own batched env (spn_torchrl/ray_evaluator.py);
    the actors are the processes, so env.processes does not apply."""

    name: str = "ray"
    address: Optional[str] = None  # a running cluster ("auto", "ray://head:10001"); None starts a local one
    num_actors: int = 2
    num_cpus_per_actor: float = 1.0
    num_cpus: Optional[int] = None  # CPUs of a local cluster started here (None: all of this machine's)
    max_restarts: int = 1  # a dead actor is restarted this many times and its shard re-run (rollouts are deterministic)
    start_timeout_s: float = 300.0  # all actors must be up (env built) within this time
    call_timeout_s: Optional[float] = None  # one population evaluation must finish within this time (None: no limit)
    ship_code: bool = False  # upload this checkout's spn_torchrl to the cluster (runtime_env py_modules)


@dataclass
class LoggerConfig:
    backend: str = "csv"  # "csv", "wandb" or "none"
    project: str = "spn_torchrl"
    entity: Optional[str] = None
    group: Optional[str] = None
    mode: str = "auto"  # wandb: "auto" (offline when there is no network), "online", "offline", "disabled"
    progress_bar: bool = False


@dataclass
class RunConfig:
    algo: Any = MISSING
    env: EnvConfig = MISSING
    logger: LoggerConfig = MISSING
    evaluator: Any = MISSING
    seed: int = 0
    resume: bool = False
    torch_threads: int = 1
    run_name: Optional[str] = None


def register_configs() -> None:
    """Register the schemas that the YAML files in conf/ extend."""
    cs = ConfigStore.instance()
    cs.store(name="run_schema", node=RunConfig)
    cs.store(group="algo", name="ga_schema", node=GAConfig)
    cs.store(group="algo", name="ppo_schema", node=PPOConfig)
    cs.store(group="env", name="env_schema", node=EnvConfig)
    cs.store(group="logger", name="logger_schema", node=LoggerConfig)
    cs.store(group="evaluator", name="local_schema", node=LocalEvaluatorConfig)
    cs.store(group="evaluator", name="ray_schema", node=RayEvaluatorConfig)


def _require(ok: bool, message: str) -> None:
    if not ok:
        raise ConfigError(message)


def validate_ga(algo: DictConfig) -> None:
    """One clear sentence per bad GA value, naming the field and the allowed range."""
    _require(
        algo.genome in ("connections", "weights"),
        f"algo.genome must be 'connections' or 'weights', got {algo.genome!r}",
    )
    _require(algo.generations >= 1, f"algo.generations must be >= 1, got {algo.generations}")
    _require(
        algo.population >= 2 and algo.population % 2 == 0,
        f"algo.population must be even and >= 2 (mirrored pairs), got {algo.population}",
    )
    _require(algo.sigma > 0, f"algo.sigma must be > 0, got {algo.sigma}")
    _require(0 < algo.truncation <= 1, f"algo.truncation must be in (0, 1], got {algo.truncation}")
    _require(0 < algo.score_threshold < 1, f"algo.score_threshold must be in (0, 1), got {algo.score_threshold}")
    _require(
        1 <= algo.elite_candidates <= algo.population,
        f"algo.elite_candidates must be in [1, algo.population={algo.population}], got {algo.elite_candidates}",
    )
    _require(algo.elite_episodes >= 1, f"algo.elite_episodes must be >= 1, got {algo.elite_episodes}")
    _require(
        algo.elite_candidates * algo.elite_episodes <= algo.population,
        "algo.elite_candidates * algo.elite_episodes must be <= algo.population (the re-evaluation runs on "
        f"the population's env), got {algo.elite_candidates} * {algo.elite_episodes} > {algo.population}",
    )
    _require(algo.hidden >= 1, f"algo.hidden must be >= 1, got {algo.hidden}")
    _require(algo.time_steps >= 1, f"algo.time_steps must be >= 1, got {algo.time_steps}")
    _require(0 <= algo.decay <= 1, f"algo.decay must be in [0, 1], got {algo.decay}")
    _require(
        0 <= algo.elitism < algo.population,
        f"algo.elitism must be in [0, algo.population), got {algo.elitism}",
    )
    _require(
        not algo.init_from_fixed_weights or algo.genome == "weights",
        "algo.init_from_fixed_weights applies only to algo.genome=weights",
    )


def validate_ppo(algo: DictConfig) -> None:
    """One clear sentence per bad PPO value, naming the field and the allowed range."""
    from spn_torchrl.snn.surrogate import SURROGATES

    _require(algo.policy in ("dpn", "spn"), f"algo.policy must be 'dpn' or 'spn', got {algo.policy!r}")
    _require(algo.frames_per_batch >= 1, f"algo.frames_per_batch must be >= 1, got {algo.frames_per_batch}")
    _require(
        algo.total_env_steps >= algo.frames_per_batch and algo.total_env_steps % algo.frames_per_batch == 0,
        f"algo.total_env_steps must be a positive multiple of algo.frames_per_batch={algo.frames_per_batch}, "
        f"got {algo.total_env_steps}",
    )
    _require(algo.epochs >= 1, f"algo.epochs must be >= 1, got {algo.epochs}")
    _require(
        1 <= algo.minibatch_size <= algo.frames_per_batch and algo.frames_per_batch % algo.minibatch_size == 0,
        f"algo.minibatch_size must be in [1, algo.frames_per_batch={algo.frames_per_batch}] and divide it, "
        f"got {algo.minibatch_size}",
    )
    _require(algo.lr_policy > 0, f"algo.lr_policy must be > 0, got {algo.lr_policy}")
    _require(algo.lr_value > 0, f"algo.lr_value must be > 0, got {algo.lr_value}")
    _require(0 <= algo.gamma <= 1, f"algo.gamma must be in [0, 1], got {algo.gamma}")
    _require(0 <= algo.gae_lambda <= 1, f"algo.gae_lambda must be in [0, 1], got {algo.gae_lambda}")
    _require(algo.clip_epsilon > 0, f"algo.clip_epsilon must be > 0, got {algo.clip_epsilon}")
    _require(algo.hidden >= 1, f"algo.hidden must be >= 1, got {algo.hidden}")
    _require(algo.eval_interval >= 1, f"algo.eval_interval must be >= 1, got {algo.eval_interval}")
    _require(algo.eval_episodes >= 1, f"algo.eval_episodes must be >= 1, got {algo.eval_episodes}")
    _require(algo.surrogate in SURROGATES, f"algo.surrogate must be one of {list(SURROGATES)}, got {algo.surrogate!r}")
    _require(algo.surrogate_alpha > 0, f"algo.surrogate_alpha must be > 0, got {algo.surrogate_alpha}")
    _require(algo.score_init_std >= 0, f"algo.score_init_std must be >= 0, got {algo.score_init_std}")
    _require(0 < algo.score_threshold < 1, f"algo.score_threshold must be in (0, 1), got {algo.score_threshold}")
    _require(algo.time_steps >= 1, f"algo.time_steps must be >= 1, got {algo.time_steps}")
    _require(0 <= algo.decay <= 1, f"algo.decay must be in [0, 1], got {algo.decay}")


def validate_ray_evaluator(evaluator: DictConfig, population: int) -> None:
    """One clear sentence per bad Ray evaluator value."""
    _require(
        1 <= evaluator.num_actors <= population,
        f"evaluator.num_actors must be in [1, algo.population={population}], got {evaluator.num_actors}",
    )
    _require(
        evaluator.num_cpus_per_actor > 0,
        f"evaluator.num_cpus_per_actor must be > 0, got {evaluator.num_cpus_per_actor}",
    )
    _require(evaluator.max_restarts >= 0, f"evaluator.max_restarts must be >= 0, got {evaluator.max_restarts}")
    _require(evaluator.start_timeout_s > 0, f"evaluator.start_timeout_s must be > 0, got {evaluator.start_timeout_s}")
    _require(
        evaluator.call_timeout_s is None or evaluator.call_timeout_s > 0,
        f"evaluator.call_timeout_s must be > 0 or null, got {evaluator.call_timeout_s}",
    )


def validate(cfg: DictConfig) -> None:
    """Check a whole run config before anything is built."""
    kind = cfg.algo.get("kind")
    _require(kind in ALGO_VALIDATORS, f"algo.kind must be one of {sorted(ALGO_VALIDATORS)}, got {kind!r}")
    ALGO_VALIDATORS[kind](cfg.algo)
    from spn_torchrl.envs import BACKENDS
    from spn_torchrl.evaluation import EVALUATORS

    _require(
        cfg.evaluator.name in EVALUATORS,
        f"evaluator.name must be one of {sorted(EVALUATORS)}, got {cfg.evaluator.name!r}",
    )
    if cfg.evaluator.name == "ray":
        validate_ray_evaluator(cfg.evaluator, cfg.algo.population)
    if cfg.evaluator.name == "local" and kind == "ga":
        _require(
            1 <= cfg.env.processes <= cfg.algo.population,
            f"env.processes must be in [1, algo.population={cfg.algo.population}], got {cfg.env.processes}",
        )
        _require(
            cfg.evaluator.start_timeout_s > 0,
            f"evaluator.start_timeout_s must be > 0, got {cfg.evaluator.start_timeout_s}",
        )

    _require(
        cfg.env.backend in BACKENDS,
        f"env.backend must be one of {sorted(BACKENDS)}, got {cfg.env.backend!r}",
    )
    _require(cfg.env.num_workers >= 1, f"env.num_workers must be >= 1, got {cfg.env.num_workers}")
    _require(cfg.torch_threads >= 1, f"torch_threads must be >= 1, got {cfg.torch_threads}")
    _require(
        cfg.logger.backend in ("csv", "wandb", "none"),
        f"logger.backend must be 'csv', 'wandb' or 'none', got {cfg.logger.backend!r}",
    )
    _require(
        cfg.logger.mode in ("auto", "online", "offline", "disabled"),
        f"logger.mode must be 'auto', 'online', 'offline' or 'disabled', got {cfg.logger.mode!r}",
    )


ALGO_VALIDATORS: dict[str, Any] = {"ga": validate_ga, "ppo": validate_ppo}
