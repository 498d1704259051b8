"""Typed run configs (Hydra structured configs) that validate themselves, before any env or worker starts.

``run()`` turns the composed config into these dataclasses once (:func:`to_run_config`); every field is checked
there, and a bad value stops the run with one sentence naming the field, the value and the allowed range.
Defaults are the paper's (SPEC.md); options that change the algorithm are off by default. The YAML files in
``conf/`` list only what differs from these schemas.
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf.errors import OmegaConfBaseException

from spn_torchrl.errors import ConfigError

GENOMES = ("connections", "weights")
POLICIES = ("dpn", "spn")
SURROGATES = ("fast_sigmoid", "atan")
BACKENDS = ("gymnasium", "mujoco_batch", "cartpole_batch", "mujoco_warp")  # envs.BACKENDS implements each
LOGGERS = ("csv", "wandb", "none")
WANDB_MODES = ("auto", "online", "offline", "disabled")
MAX_SIZE = 100_000  # populations, generations, widths: what a 2-core machine can hold at all
MAX_SEED = 2**63 - 1


def _check(ok: bool, name: str, value: Any, allowed: str) -> None:
    if not ok:
        raise ConfigError(f"{name} must be {allowed}, got {value!r}")


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _int_in(name: str, value: Any, low: int, high: int) -> None:
    ok = isinstance(value, int) and not isinstance(value, bool) and low <= value <= high
    _check(ok, name, value, f"an integer in [{low}, {high}]")


def _number(
    name: str,
    value: Any,
    low: float | None = None,
    high: float | None = None,
    *,
    open_low: bool = False,
    open_high: bool = False,
) -> None:
    """A finite number in a range (bounds None: unbounded; open_*: the bound itself excluded)."""
    ok = _finite(value)
    if ok and low is not None:
        ok = value > low if open_low else value >= low
    if ok and high is not None:
        ok = value < high if open_high else value <= high
    left = "(-inf" if low is None else f"{'(' if open_low else '['}{low:g}"
    right = "inf)" if high is None else f"{high:g}{')' if open_high else ']'}"
    _check(ok, name, value, f"a finite number in {left}, {right}")


def _choice(name: str, value: Any, choices: tuple[str, ...]) -> None:
    _check(value in choices, name, value, f"one of {', '.join(map(repr, choices))}")


@dataclass
class SNNConfig:
    """The SPN of SPEC.md: 64 LIF neurons, T' = 4 simulation steps per env step, decay g = 0.75, threshold
    v_th = 0.5 (strict), connection threshold s_th = 0.5 on sigmoid(score). Shared by the GA and Connections-PPO."""

    hidden: int = 64
    time_steps: int = 4
    decay: float = 0.75
    v_threshold: float = 0.5
    score_threshold: float = 0.5

    def validate(self, at: str) -> None:
        _int_in(f"{at}.hidden", self.hidden, 1, 4096)
        _int_in(f"{at}.time_steps", self.time_steps, 1, 64)
        _number(f"{at}.decay", self.decay, 0, 1)
        _number(f"{at}.v_threshold", self.v_threshold)
        _number(f"{at}.score_threshold", self.score_threshold, 0, 1, open_low=True, open_high=True)


@dataclass
class GAConfig:
    """Connections-GA / Weights-GA (SPEC.md: G=100, N=200, sigma=0.01, eta=0.25, top 10 re-evaluated 10 times)."""

    name: str = "conn_ga"
    kind: str = "ga"
    genome: str = "connections"  # "connections" (scores, masked fixed weights) or "weights"
    generations: int = 100
    population: int = 200
    sigma: float = 0.01
    truncation: float = 0.25
    elite_candidates: int = 10
    elite_episodes: int = 10
    snn: SNNConfig = field(default_factory=SNNConfig)
    elitism: int = 0  # option: keep the k best unchanged (the paper keeps none)
    init_from_fixed_weights: bool = False  # option (Weights-GA): start around the Kaiming weights, not 0

    def validate(self, at: str = "algo") -> None:
        _choice(f"{at}.genome", self.genome, GENOMES)
        _int_in(f"{at}.generations", self.generations, 1, MAX_SIZE)
        _int_in(f"{at}.population", self.population, 2, MAX_SIZE)
        _check(self.population % 2 == 0, f"{at}.population", self.population, "even (mirrored pairs)")
        _number(f"{at}.sigma", self.sigma, 0, None, open_low=True)
        _number(f"{at}.truncation", self.truncation, 0, 1, open_low=True)
        _int_in(f"{at}.elite_candidates", self.elite_candidates, 1, self.population)
        _int_in(f"{at}.elite_episodes", self.elite_episodes, 1, self.population // self.elite_candidates)
        self.snn.validate(f"{at}.snn")
        _int_in(f"{at}.elitism", self.elitism, 0, self.population - 1)
        _check(
            not self.init_from_fixed_weights or self.genome == "weights",
            f"{at}.init_from_fixed_weights",
            self.init_from_fixed_weights,
            f"false unless {at}.genome=weights",
        )

    @property
    def evaluation_slots(self) -> int:
        """Env slots a generation needs: the population and the previous generation's re-evaluation, which run
        in one rollout."""
        return self.population + self.elite_candidates * self.elite_episodes


@dataclass
class PPOConfig:
    """DPN-PPO / Connections-PPO (SPEC.md, paper appendix): 1e6 steps as 1e3 iterations of 1e3 steps, 25 epochs of
    minibatches of 100, Adam 1e-5 (policy) / 1e-4 (value), gamma 0.99, lambda 0.95, clip 0.2."""

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
    hidden: int = 64  # the DPN's and the value net's hidden width
    log_std_init: float = -0.5  # Spinning Up's initial log-std of the Gaussian
    eval_interval: int = 10  # iterations between deterministic evaluations (the last one is always evaluated)
    eval_episodes: int = 10
    # Connections-PPO (policy=spn): the GA's SPN, its surrogate spike derivative and its scores' initial spread
    snn: SNNConfig = field(default_factory=SNNConfig)
    surrogate: str = "fast_sigmoid"
    surrogate_alpha: float = 2.0
    score_init_std: float = 0.01

    def validate(self, at: str = "algo") -> None:
        _choice(f"{at}.policy", self.policy, POLICIES)
        _int_in(f"{at}.frames_per_batch", self.frames_per_batch, 1, 1_000_000)
        _int_in(f"{at}.total_env_steps", self.total_env_steps, self.frames_per_batch, 10**10)
        _check(
            self.total_env_steps % self.frames_per_batch == 0,
            f"{at}.total_env_steps",
            self.total_env_steps,
            f"a multiple of {at}.frames_per_batch={self.frames_per_batch}",
        )
        _int_in(f"{at}.epochs", self.epochs, 1, 1000)
        _int_in(f"{at}.minibatch_size", self.minibatch_size, 1, self.frames_per_batch)
        _check(
            self.frames_per_batch % self.minibatch_size == 0,
            f"{at}.minibatch_size",
            self.minibatch_size,
            f"a divisor of {at}.frames_per_batch={self.frames_per_batch}",
        )
        _number(f"{at}.lr_policy", self.lr_policy, 0, None, open_low=True)
        _number(f"{at}.lr_value", self.lr_value, 0, None, open_low=True)
        _number(f"{at}.gamma", self.gamma, 0, 1)
        _number(f"{at}.gae_lambda", self.gae_lambda, 0, 1)
        _number(f"{at}.clip_epsilon", self.clip_epsilon, 0, None, open_low=True)
        _int_in(f"{at}.hidden", self.hidden, 1, 4096)
        _number(f"{at}.log_std_init", self.log_std_init, -20, 2)
        _int_in(f"{at}.eval_interval", self.eval_interval, 1, MAX_SIZE)
        _int_in(f"{at}.eval_episodes", self.eval_episodes, 1, 1000)
        self.snn.validate(f"{at}.snn")
        _choice(f"{at}.surrogate", self.surrogate, SURROGATES)
        _number(f"{at}.surrogate_alpha", self.surrogate_alpha, 0, None, open_low=True)
        _number(f"{at}.score_init_std", self.score_init_std, 0, None)


@dataclass
class EnvConfig:
    """The task and the backend that steps its copies."""

    name: str = MISSING
    id: str = MISSING  # a Gymnasium id with a flat Box observation
    backend: str = "gymnasium"
    threads: int = 1  # mujoco_batch: physics threads of each env (the other backends step in one thread)
    device: str = "cpu"  # mujoco_warp: "cpu", "cuda" or "cuda:<index>" (the other backends run on the CPU)

    def validate(self, at: str = "env") -> None:
        _check(isinstance(self.name, str) and bool(self.name), f"{at}.name", self.name, "a non-empty name")
        _check(isinstance(self.id, str) and bool(self.id), f"{at}.id", self.id, "a Gymnasium environment id")
        _choice(f"{at}.backend", self.backend, BACKENDS)
        _int_in(f"{at}.threads", self.threads, 1, 256)
        _check(
            self.threads == 1 or self.backend == "mujoco_batch",
            f"{at}.threads",
            self.threads,
            f"1 for env.backend={self.backend} (only mujoco_batch runs physics threads)",
        )
        device_ok = isinstance(self.device, str) and re.fullmatch(r"cpu|cuda(:\d+)?", self.device) is not None
        _check(device_ok, f"{at}.device", self.device, "cpu, cuda or cuda:<index>")
        _check(
            self.device == "cpu" or self.backend == "mujoco_warp",
            f"{at}.device",
            self.device,
            f"cpu for env.backend={self.backend} (only mujoco_warp runs on a device)",
        )


@dataclass
class LocalEvaluatorConfig:
    """The population on this machine: in this process, or in worker processes that each run a shard."""

    name: str = "local"
    # GA worker processes, each running a shard of the population (its own env and SPN); None: the cores this
    # process may use divided by env.threads. The episodes are the same for any value.
    processes: Optional[int] = None
    start_timeout_s: float = 300.0  # the worker processes must be up (envs built) within this time
    call_timeout_s: Optional[float] = 3600.0  # one population evaluation must finish within this time (None: no limit)

    def validate(self, at: str = "evaluator") -> None:
        if self.processes is not None:
            _int_in(f"{at}.processes", self.processes, 1, 256)
        _number(f"{at}.start_timeout_s", self.start_timeout_s, 0, None, open_low=True)
        if self.call_timeout_s is not None:
            _number(f"{at}.call_timeout_s", self.call_timeout_s, 0, None, open_low=True)


@dataclass
class RayEvaluatorConfig:
    """The population sharded across Ray actors, each stepping its own batched env (spn_torchrl/evaluation/ray.py)."""

    name: str = "ray"
    address: Optional[str] = None  # a running cluster ("auto", "ray://head:10001"); None starts a local one
    num_actors: int = 2
    num_cpus_per_actor: float = 1.0
    num_cpus: Optional[int] = None  # CPUs of a local cluster started here (None: all of this machine's)
    max_restarts: int = 1  # a dead actor is restarted this many times and its shard re-run (rollouts are deterministic)
    start_timeout_s: float = 300.0  # all actors must be up (env built) within this time
    call_timeout_s: Optional[float] = None  # one population evaluation must finish within this time (None: no limit)
    ship_code: bool = False  # upload this checkout's spn_torchrl to the cluster (runtime_env py_modules)

    def validate(self, at: str = "evaluator") -> None:
        _int_in(f"{at}.num_actors", self.num_actors, 1, 10_000)
        _number(f"{at}.num_cpus_per_actor", self.num_cpus_per_actor, 0, 1024, open_low=True)
        if self.num_cpus is not None:
            _int_in(f"{at}.num_cpus", self.num_cpus, 1, 100_000)
        _int_in(f"{at}.max_restarts", self.max_restarts, 0, 100)
        _number(f"{at}.start_timeout_s", self.start_timeout_s, 0, None, open_low=True)
        if self.call_timeout_s is not None:
            _number(f"{at}.call_timeout_s", self.call_timeout_s, 0, None, open_low=True)


@dataclass
class LoggerConfig:
    backend: str = "csv"  # "csv", "wandb" or "none"
    project: str = "spn_torchrl"
    entity: Optional[str] = None
    group: Optional[str] = None
    mode: str = "auto"  # wandb: "auto" (offline when there are no credentials), "online", "offline", "disabled"
    progress_bar: bool = False

    def validate(self, at: str = "logger") -> None:
        _choice(f"{at}.backend", self.backend, LOGGERS)
        _choice(f"{at}.mode", self.mode, WANDB_MODES)


@dataclass
class RunConfig:
    """One run: the method (``algo``: a GA or a PPO config), the task, the logger and the evaluator (a local or a
    Ray config). Validates every field on construction."""

    algo: Any = MISSING  # GAConfig | PPOConfig
    env: EnvConfig = MISSING
    logger: LoggerConfig = MISSING
    evaluator: Any = MISSING  # LocalEvaluatorConfig | RayEvaluatorConfig
    seed: int = 0
    resume: bool = False
    torch_threads: int = 1
    run_name: Optional[str] = None
    # option (not the paper's, which ran its seeds apart): the seeds of GA runs evolved in lockstep in this process,
    # each in its own directory; null: one run of ``seed`` (spn_torchrl.training.lockstep)
    lockstep: Optional[list[int]] = None

    def __post_init__(self) -> None:
        if any(value is MISSING or value == MISSING for value in (self.algo, self.env, self.logger, self.evaluator)):
            return  # the schema itself, before composition
        _check(isinstance(self.algo, (GAConfig, PPOConfig)), "algo", self.algo, "a GA or a PPO config (conf/algo)")
        _check(
            isinstance(self.evaluator, (LocalEvaluatorConfig, RayEvaluatorConfig)),
            "evaluator",
            self.evaluator,
            "a local or a Ray evaluator config (conf/evaluator)",
        )
        self.algo.validate("algo")
        self.env.validate("env")
        self.logger.validate("logger")
        self.evaluator.validate("evaluator")
        _int_in("seed", self.seed, 0, MAX_SEED)
        _int_in("torch_threads", self.torch_threads, 1, 256)
        if isinstance(self.evaluator, RayEvaluatorConfig):
            _check(
                isinstance(self.algo, GAConfig),
                "evaluator",
                "ray",
                f"local for algo={self.algo.name} (Ray actors evaluate GA populations; PPO trains one policy here)",
            )
            _int_in("evaluator.num_actors", self.evaluator.num_actors, 1, self.algo.population)
        if self.lockstep is not None:
            self._check_lockstep()
        if self.env.backend == "mujoco_warp":
            _check(
                isinstance(self.evaluator, LocalEvaluatorConfig) and self.evaluator.processes in (None, 1),
                "evaluator",
                self.evaluator.name,
                "local with evaluator.processes 1 or null for env.backend=mujoco_warp (one device holds every world)",
            )

    def _check_lockstep(self) -> None:
        seeds = list(self.lockstep)
        _check(bool(seeds), "lockstep", seeds, "null or a non-empty list of seeds")
        for seed in seeds:
            _int_in("lockstep seeds", seed, 0, MAX_SEED)
        _check(len(set(seeds)) == len(seeds), "lockstep", seeds, "a list of distinct seeds")
        _check(self.seed == 0, "seed", self.seed, "0 (its default) with lockstep, whose list gives the runs' seeds")
        _check(isinstance(self.algo, GAConfig), "lockstep", seeds, f"null for algo={self.algo.name} (GA runs only)")
        _check(
            isinstance(self.evaluator, LocalEvaluatorConfig),
            "lockstep",
            seeds,
            "null for evaluator=ray (lockstep runs share this machine's evaluator)",
        )

    @property
    def is_ga(self) -> bool:
        return isinstance(self.algo, GAConfig)


def seeds_label(seed: Any, lockstep: Any) -> str:
    """The seed part of a job's Hydra directory (``${seeds:${seed},${lockstep}}`` in conf/config.yaml): ``seed``,
    or with ``lockstep`` its seeds joined by '-' (``0-1-2``), so that the jobs of a multirun over lockstep
    batches (``-m lockstep=[0,1],[2,3]``) get their own directories."""
    return str(seed) if lockstep is None else "-".join(str(s) for s in lockstep)


def register_configs() -> None:
    """Register the schemas that the YAML files in conf/ extend, and the ``seeds`` resolver their Hydra
    directories use."""
    OmegaConf.register_new_resolver("seeds", seeds_label, replace=True)
    cs = ConfigStore.instance()
    cs.store(name="run_schema", node=RunConfig)
    cs.store(group="algo", name="ga_schema", node=GAConfig)
    cs.store(group="algo", name="ppo_schema", node=PPOConfig)
    cs.store(group="env", name="env_schema", node=EnvConfig)
    cs.store(group="logger", name="logger_schema", node=LoggerConfig)
    cs.store(group="evaluator", name="local_schema", node=LocalEvaluatorConfig)
    cs.store(group="evaluator", name="ray_schema", node=RayEvaluatorConfig)


SCHEMAS = {
    "algo": {"ga": GAConfig, "ppo": PPOConfig},
    "evaluator": {"local": LocalEvaluatorConfig, "ray": RayEvaluatorConfig},
}


def _unknown_keys(node: Any, schema: type, at: str) -> None:
    """A sentence for the first key of ``node`` that ``schema`` does not have (e.g. ``+algo.foo=1``)."""
    fields = {f.name: f for f in dataclasses.fields(schema)}
    for key in node:
        if key not in fields:
            raise ConfigError(
                f"{at}.{key} is not a field of {at} ({schema.__name__}): expected one of {', '.join(fields)}"
            )
        inner = fields[key].type
        value = node[key]
        if isinstance(value, DictConfig) and isinstance(inner, str) and inner in _NESTED:
            _unknown_keys(value, _NESTED[inner], f"{at}.{key}")


_NESTED = {"SNNConfig": SNNConfig, "EnvConfig": EnvConfig, "LoggerConfig": LoggerConfig}


def _schema_of(group: str, node: Any) -> type | None:
    """The dataclass a composed group node belongs to (None if it names none)."""
    if not isinstance(node, DictConfig):
        return None
    kind = node.get("kind") if group == "algo" else node.get("name")
    return SCHEMAS[group].get(kind) if isinstance(kind, str) else None


def to_run_config(cfg: DictConfig | dict) -> RunConfig:
    """The typed, validated config of a composed (or saved) one; ConfigError naming the first bad field."""
    cfg = cfg if isinstance(cfg, DictConfig) else OmegaConf.create(cfg)
    plain = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
    for group in ("algo", "evaluator"):
        node = plain.get(group)
        schema = _schema_of(group, node)
        what = "algo.kind ('ga' or 'ppo')" if group == "algo" else "evaluator.name ('local' or 'ray')"
        _check(
            schema is not None, group, None if node is None else OmegaConf.to_container(node), f"a config with {what}"
        )
        _unknown_keys(node, schema, group)
    for group, schema in (("env", EnvConfig), ("logger", LoggerConfig)):
        _check(isinstance(plain.get(group), DictConfig), group, plain.get(group), "a config group (conf/" + group + ")")
        _unknown_keys(plain[group], schema, group)
    try:
        typed = OmegaConf.structured(RunConfig)
        typed.algo = OmegaConf.structured(_schema_of("algo", plain.algo))
        typed.evaluator = OmegaConf.structured(_schema_of("evaluator", plain.evaluator))
        typed = OmegaConf.merge(typed, plain)
        return OmegaConf.to_object(typed)
    except OmegaConfBaseException as err:
        key = getattr(err, "full_key", None) or "config"
        raise ConfigError(f"{key}: {str(err).splitlines()[0]}") from None


def config_dict(cfg: RunConfig) -> dict[str, Any]:
    """A run config as plain nested dicts (what W&B receives and a checkpoint stores)."""
    return dataclasses.asdict(cfg)


def config_yaml(cfg: RunConfig) -> str:
    return OmegaConf.to_yaml(OmegaConf.create(config_dict(cfg)))


LEGACY_SNN = ("hidden", "time_steps", "decay", "v_threshold", "score_threshold")


def from_saved(saved: str | dict[str, Any]) -> RunConfig:
    """The run config a checkpoint saved (a dict, or YAML in earlier versions), including the flat layout of
    earlier versions (the SNN constants under ``algo.``, ``env.num_workers`` and ``env.processes``)."""
    saved = OmegaConf.to_container(OmegaConf.create(saved), resolve=True)
    algo, env, evaluator = saved.get("algo", {}), saved.get("env", {}), saved.get("evaluator", {})
    if "snn" not in algo:
        snn = {key: algo.pop(key) for key in LEGACY_SNN if key in algo}
        if algo.get("kind") == "ppo" and "hidden" in snn:
            algo["hidden"] = snn["hidden"]  # the DPN's width and the SPN's were one field
        algo["snn"] = snn
    if "num_workers" in env:
        env["threads"] = env.pop("num_workers")
    if "processes" in env:
        processes = env.pop("processes")
        if evaluator.get("name") == "local":
            evaluator.setdefault("processes", processes)
    return to_run_config(saved)
