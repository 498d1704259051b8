"""Typed run configs (Hydra structured configs) that validate themselves, before any env or worker starts.

``run()`` turns the composed config into these dataclasses once (:func:`to_run_config`); every field is checked
there, and a bad value stops the run with one sentence naming the field, the value and the allowed range.
Defaults are the paper's (SPEC.md); options that change the algorithm are off by default. The YAML files in
``conf/`` list only what differs from these schemas. Each field's comment (on its line, or the lines just above
it) says what it is and ends with ``source: WHERE`` (SPEC.md's section, or the project for what the paper does not
fix); the docs' configuration page is generated from these comments (``docs/hooks.py``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from typing import Any, Optional

from hydra.core.config_store import ConfigStore
from omegaconf import MISSING, DictConfig, OmegaConf
from omegaconf.errors import InterpolationValidationError, OmegaConfBaseException

from spn_torchrl.errors import ConfigError

GENOMES = ("connections", "weights")
POLICIES = ("dpn", "spn")
SURROGATES = ("fast_sigmoid", "atan")
BACKENDS = (
    "gymnasium",
    "mujoco_batch",
    "cartpole_batch",
    "mujoco_warp",
    "gym_v2",
    "mujoco_batch_mj210",
)  # envs.BACKENDS implements each
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


def _file_name(name: str, value: Any) -> None:
    """A name that becomes part of a path (logs/, a collected run's directory): one file name, never a way out."""
    ok = isinstance(value, str) and re.fullmatch(r"[A-Za-z0-9_.+=-]+", value) is not None and value not in (".", "..")
    _check(ok, name, value, "a file name of letters, digits and _ . + = - (no path separator, not '.' or '..')")


def _choice(name: str, value: Any, choices: tuple[str, ...]) -> None:
    _check(value in choices, name, value, f"one of {', '.join(map(repr, choices))}")


@dataclass
class SNNConfig:
    """The SPN of SPEC.md: 64 LIF neurons, T' = 4 simulation steps per env step, decay g = 0.75, threshold
    v_th = 0.5 (strict), connection threshold s_th = 0.5 on sigmoid(score). Shared by the GA and Connections-PPO."""

    hidden: int = 64  # LIF neurons in the hidden layer; source: SPEC.md, SPN
    # simulation steps T' per env step, the observation held as a constant current; source: SPEC.md, SPN
    time_steps: int = 4
    decay: float = 0.75  # membrane decay g of the LIF and LI neurons; source: SPEC.md, SPN
    v_threshold: float = 0.5  # LIF spike threshold v_th, strict (v > v_th); source: SPEC.md, SPN
    # connection threshold s_th: a synapse exists where sigmoid(score) >= s_th; source: SPEC.md, SPN
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

    name: str = "conn_ga"  # the method's name in run directories and W&B (conf/algo/NAME.yaml); source: project
    kind: str = "ga"  # the schema a composed algo belongs to: "ga" or "ppo"; source: project
    # "connections" (scores, masked fixed weights: Connections-GA) or "weights" (Weights-GA); source: SPEC.md, GA
    genome: str = "connections"
    generations: int = 100  # G, generations of a run; source: SPEC.md, GA (paper budget)
    population: int = 200  # N, individuals per generation, in mirrored pairs; source: SPEC.md, GA (paper budget)
    sigma: float = 0.01  # mutation std of each gene; source: SPEC.md, GA (paper budget)
    truncation: float = 0.25  # eta: the top eta*N by fitness are the parents; source: SPEC.md, GA (paper budget)
    elite_candidates: int = 10  # the top K by single-episode fitness, re-evaluated; source: SPEC.md, GA (elite)
    elite_episodes: int = 10  # new episodes per elite candidate; source: SPEC.md, GA (elite)
    snn: SNNConfig = field(default_factory=SNNConfig)  # the SPN's constants (algo.snn.*); source: SPEC.md, SPN
    # option: keep the k best unchanged (the paper keeps none); source: SPEC.md, GA (a natural option)
    elitism: int = 0
    # option (Weights-GA): start around the Kaiming weights, not 0; source: SPEC.md, GA (a natural option)
    init_from_fixed_weights: bool = False

    def validate(self, at: str = "algo") -> None:
        _file_name(f"{at}.name", self.name)
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
class ECConfig:
    """Connections-EC (beyond the paper): Evolving Connectivity's NES on each synapse's existence probability
    (Wang et al., NeurIPS 2023; github.com/imoneoi/EvolvingConnectivity at 3e61be4, ``ec.py``), on the paper's SPN
    and fixed weights, at the paper's budget.

    From their ``ec.py``: p starts at 0.5 (``_runner_init``, l. 184); a generation samples masks ``uniform < p``
    (``_sample_bernoulli_parameter``, l. 107); fitness gets the centered rank ``rank / (N - 1) - 0.5``
    (``_centered_rank_transform``, l. 88-96); the NES gradient is ``mean_i w_i (x_i - p)`` (``_nes_grad``, l. 275-278),
    ascended by Adam (optax ``scale_by_adam`` defaults b1 0.9, b2 0.999, eps 1e-8, then ``scale(-lr)``, l. 352-356)
    with ``lr`` 0.15 (``ESConfig.lr``, l. 43); p is clipped to ``[eps, 1 - eps]`` with ``eps`` 1e-3 (``ESConfig.eps``,
    l. 45; l. 287); the deterministic mask is ``p > 0.5`` (``_deterministic_bernoulli_parameter``, l. 113-116).
    Where EC and the paper differ the paper's budget holds: N = 200 masks (EC: ``pop_size`` 10240, l. 42) for 100
    generations (EC: ``total_generations`` 1000, l. 317), one episode of fitness each (EC averages the episodes an
    individual finishes while the slowest finishes one, l. 254-258, 270). The logged return is the GA's: the
    elite, here the deterministic mask of the p that sampled the generation (EC's ``eval_fitness``, l. 210, 297),
    gets ``elite_episodes`` fresh episodes (SPEC.md). ``snn.score_threshold`` plays no part: a mask is sampled, not
    thresholded from scores."""

    name: str = "conn_ec"  # the method's name in run names and reports; source: project
    kind: str = "ec"  # the training loop that runs it; source: project
    generations: int = 100  # the paper's budget, not EC's 1000 (ec.py l. 317); source: SPEC.md, GA
    population: int = 200  # the paper's N, not EC's pop_size 10240 (ec.py l. 42); source: SPEC.md, GA
    lr: float = 0.15  # Adam's step on p; source: EvolvingConnectivity ec.py l. 43 (ESConfig.lr)
    eps: float = 1e-3  # p is clipped to [eps, 1 - eps]; source: EvolvingConnectivity ec.py l. 45, 287
    p_init: float = 0.5  # every connection's initial probability; source: EvolvingConnectivity ec.py l. 184
    adam_b1: float = 0.9  # Adam's b1; source: optax scale_by_adam defaults, EvolvingConnectivity ec.py l. 353
    adam_b2: float = 0.999  # Adam's b2; source: optax scale_by_adam defaults, EvolvingConnectivity ec.py l. 353
    adam_eps: float = 1e-8  # Adam's eps; source: optax scale_by_adam defaults, EvolvingConnectivity ec.py l. 353
    # fresh episodes of the one deterministic mask that give the logged return; source: SPEC.md, GA
    elite_episodes: int = 10
    snn: SNNConfig = field(default_factory=SNNConfig)  # the SPN's constants (algo.snn.*); source: SPEC.md, SPN

    def validate(self, at: str = "algo") -> None:
        _int_in(f"{at}.generations", self.generations, 1, MAX_SIZE)
        _int_in(f"{at}.population", self.population, 2, MAX_SIZE)
        _number(f"{at}.lr", self.lr, 0, None, open_low=True)
        _number(f"{at}.eps", self.eps, 0, 0.5, open_low=True, open_high=True)
        _number(f"{at}.p_init", self.p_init, self.eps, 1 - self.eps)
        _number(f"{at}.adam_b1", self.adam_b1, 0, 1, open_high=True)
        _number(f"{at}.adam_b2", self.adam_b2, 0, 1, open_high=True)
        _number(f"{at}.adam_eps", self.adam_eps, 0, None, open_low=True)
        _int_in(f"{at}.elite_episodes", self.elite_episodes, 1, self.population)
        self.snn.validate(f"{at}.snn")

    @property
    def genome(self) -> str:
        """EC's masks travel as connection genomes (scores of +-inf), so every GA tool reads them."""
        return "connections"

    @property
    def elite_candidates(self) -> int:
        """One elite is re-evaluated: the deterministic mask."""
        return 1

    @property
    def evaluation_slots(self) -> int:
        """Env slots a generation needs: the masks and the previous generation's re-evaluation, in one rollout."""
        return self.population + self.elite_episodes


EVOLUTION = (GAConfig, ECConfig)  # the methods that evaluate populations with the GA's evaluators and run loop


@dataclass
class PPOConfig:
    """DPN-PPO / Connections-PPO (SPEC.md, paper appendix): 1e6 steps as 1e3 iterations of 1e3 steps, 25 epochs of
    minibatches of 100, Adam 1e-5 (policy) / 1e-4 (value), gamma 0.99, lambda 0.95, clip 0.2."""

    name: str = "dpn_ppo"  # the method's name in run directories and W&B (conf/algo/NAME.yaml); source: project
    kind: str = "ppo"  # the schema a composed algo belongs to: "ga" or "ppo"; source: project
    # "dpn" (n -> hidden ReLU -> m Tanh) or "spn" (the GA's SPN, its scores trained); source: SPEC.md, PPO
    policy: str = "dpn"
    total_env_steps: int = 1_000_000  # the budget in env steps; source: SPEC.md, PPO
    frames_per_batch: int = 1000  # env steps collected per iteration; source: SPEC.md, PPO
    epochs: int = 25  # passes over each iteration's steps; source: SPEC.md, PPO
    minibatch_size: int = 100  # steps per gradient step; source: SPEC.md, PPO
    lr_policy: float = 1e-5  # Adam's learning rate of the policy; source: SPEC.md, PPO
    lr_value: float = 1e-4  # Adam's learning rate of the value net; source: SPEC.md, PPO
    gamma: float = 0.99  # discount; source: SPEC.md, PPO
    gae_lambda: float = 0.95  # GAE lambda; source: SPEC.md, PPO
    clip_epsilon: float = 0.2  # PPO's clip range; source: SPEC.md, PPO
    normalize_advantage: bool = True  # advantages normalised per batch; source: Spinning Up's PPO (paper appendix)
    hidden: int = 64  # the DPN's and the value net's hidden width; source: SPEC.md, PPO
    log_std_init: float = -0.5  # initial log-std of the Gaussian; source: Spinning Up's PPO (paper appendix)
    # iterations between deterministic evaluations (the last one is always evaluated); source: project
    eval_interval: int = 10
    eval_episodes: int = 10  # episodes per deterministic evaluation, as the GA's elite; source: project
    snn: SNNConfig = field(
        default_factory=SNNConfig
    )  # Connections-PPO (policy=spn): the GA's SPN; source: SPEC.md, SPN
    # Connections-PPO: the surrogate spike derivative, "fast_sigmoid" or "atan"; source: project (SPEC.md names none)
    surrogate: str = "fast_sigmoid"
    surrogate_alpha: float = 2.0  # Connections-PPO: the surrogate's sharpness; source: project
    score_init_std: float = 0.01  # Connections-PPO: the initial scores' std (the GA's sigma); source: project

    def validate(self, at: str = "algo") -> None:
        _file_name(f"{at}.name", self.name)
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

    name: str = MISSING  # the task's name in run directories (conf/env/NAME.yaml); source: project
    id: str = MISSING  # a Gymnasium id with a flat Box observation; source: SPEC.md, Environments
    # what steps the copies: gymnasium (the reference for any id), mujoco_batch, cartpole_batch, mujoco_warp,
    # gym_v2 (the paper's Gym 0.21 + mujoco-py), mujoco_batch_mj210
    # (conf/env sets each task's default); source: project (spn_torchrl/envs)
    backend: str = "gymnasium"
    # mujoco_batch(_mj210): physics threads of each env; gym_v2: worker processes of each env (the others step in
    # one thread); source: project
    threads: int = 1
    # mujoco_warp: "cpu", "cuda" or "cuda:<index>" (the other backends run on the CPU); source: project
    device: str = "cpu"

    def validate(self, at: str = "env") -> None:
        _file_name(f"{at}.name", self.name)
        _check(isinstance(self.id, str) and bool(self.id), f"{at}.id", self.id, "a Gymnasium environment id")
        _choice(f"{at}.backend", self.backend, BACKENDS)
        _int_in(f"{at}.threads", self.threads, 1, 256)
        _check(
            self.threads == 1 or self.backend in ("mujoco_batch", "mujoco_batch_mj210", "gym_v2"),
            f"{at}.threads",
            self.threads,
            f"1 for env.backend={self.backend} (only mujoco_batch and gym_v2 step on several threads or processes)",
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

    name: str = "local"  # the schema a composed evaluator belongs to: "local" or "ray"; source: project
    # GA worker processes, each running a shard of the population (its own env and SPN); None: the cores this
    # process may use divided by env.threads. The episodes are the same for any value; source: project
    processes: Optional[int] = None
    # seconds within which the worker processes must be up (envs built); source: project
    start_timeout_s: float = 300.0
    # seconds within which one population evaluation must finish (None: no limit); source: project
    call_timeout_s: Optional[float] = 3600.0

    def validate(self, at: str = "evaluator") -> None:
        if self.processes is not None:
            _int_in(f"{at}.processes", self.processes, 1, 256)
        _number(f"{at}.start_timeout_s", self.start_timeout_s, 0, None, open_low=True)
        if self.call_timeout_s is not None:
            _number(f"{at}.call_timeout_s", self.call_timeout_s, 0, None, open_low=True)


@dataclass
class RayEvaluatorConfig:
    """The population sharded across Ray actors, each stepping its own batched env (spn_torchrl/evaluation/ray.py)."""

    name: str = "ray"  # the schema a composed evaluator belongs to: "local" or "ray"; source: project
    # a running cluster ("auto", "ray://head:10001"); None starts a local one; source: project
    address: Optional[str] = None
    num_actors: int = 2  # Ray actors, each evaluating one shard of the population; source: project
    num_cpus_per_actor: float = 1.0  # CPUs Ray reserves for each actor; source: project
    # CPUs of a local cluster started here (None: all of this machine's); source: project
    num_cpus: Optional[int] = None
    # a dead actor is restarted this many times and its shard re-run (rollouts are deterministic); source: project
    max_restarts: int = 1
    start_timeout_s: float = 300.0  # seconds within which all actors must be up (env built); source: project
    # seconds within which one population evaluation must finish (None: no limit); source: project
    call_timeout_s: Optional[float] = None
    # upload this checkout's spn_torchrl to the cluster (runtime_env py_modules); source: project
    ship_code: bool = False

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
    """Where the metrics go: CSV files under the run directory, W&B, or nowhere (progress.csv is always written)."""

    backend: str = "csv"  # "csv", "wandb" or "none"; source: project
    project: str = "spn_torchrl"  # wandb: the W&B project; source: project
    entity: Optional[str] = None  # wandb: the W&B entity (None: the account's default); source: project
    # wandb: the W&B group (None: the sweep directory's name, so one sweep's runs share a group); source: project
    group: Optional[str] = None
    # wandb: "auto" (offline without an API key or a server that answers), "online", "offline", "disabled"; source: project
    mode: str = "auto"
    # a tqdm bar while stderr is a terminal (never off one: a pipe, a Slurm log); False: the log lines alone; source:
    # project (issue 45)
    progress_bar: bool = True

    def validate(self, at: str = "logger") -> None:
        _choice(f"{at}.backend", self.backend, LOGGERS)
        _choice(f"{at}.mode", self.mode, WANDB_MODES)


@dataclass
class RunConfig:
    """One run: the method (``algo``: a GA or a PPO config), the task, the logger and the evaluator (a local or a
    Ray config). Validates every field on construction."""

    algo: Any = MISSING  # the method (conf/algo): GAConfig | ECConfig | PPOConfig; source: project
    env: EnvConfig = MISSING  # the task (conf/env); source: project
    logger: LoggerConfig = MISSING  # the logger (conf/logger); source: project
    # the evaluator (conf/evaluator): LocalEvaluatorConfig | RayEvaluatorConfig; source: project
    evaluator: Any = MISSING
    # the run seed: fixed weights, generation 0 and every episode's env seed derive from it; source: SPEC.md, SPN
    seed: int = 0
    resume: bool = False  # continue the run in hydra.run.dir from its checkpoint; source: project
    torch_threads: int = 1  # torch's intra-op threads (physics threads are env.threads); source: project
    # the run's name in logs and W&B (None: {env}__{algo}__{seed}, with __{unix time} outside a sweep); source: project
    run_name: Optional[str] = None
    # option (beyond the paper): every method's policy sees (obs - mean) / std of running statistics, EC's
    # (ec.py l. 125, 263: brax running_statistics), updated after each generation or iteration from the
    # observations its policies saw (spn_torchrl/snn/observations.py); the paper's policies see raw observations;
    # source: EvolvingConnectivity ec.py
    normalize_observations: bool = False
    # option (beyond the paper, which ran its seeds apart): the seeds of GA or EC runs evolved in lockstep in this
    # process, each in its own directory; null: one run of ``seed`` (spn_torchrl/training/lockstep.py); source: project
    lockstep: Optional[list[int]] = None

    def __post_init__(self) -> None:
        if any(value is MISSING or value == MISSING for value in (self.algo, self.env, self.logger, self.evaluator)):
            return  # the schema itself, before composition
        _check(
            isinstance(self.algo, (*EVOLUTION, PPOConfig)), "algo", self.algo, "a GA, an EC or a PPO config (conf/algo)"
        )
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
        _check(
            isinstance(self.normalize_observations, bool),
            "normalize_observations",
            self.normalize_observations,
            "true or false",
        )
        _check(
            not self.normalize_observations or self.env.backend != "mujoco_warp",
            "normalize_observations",
            self.normalize_observations,
            "false for env.backend=mujoco_warp (its device loop does not gather observation statistics yet)",
        )
        if self.run_name is not None:
            _file_name("run_name", self.run_name)
        if isinstance(self.evaluator, RayEvaluatorConfig):
            _check(
                isinstance(self.algo, EVOLUTION),
                "evaluator",
                "ray",
                f"local for algo={self.algo.name} (Ray actors evaluate GA or EC populations; PPO trains one policy here)",
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
        _check(
            isinstance(self.algo, EVOLUTION), "lockstep", seeds, f"null for algo={self.algo.name} (GA or EC runs only)"
        )
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
    cs.store(group="algo", name="ec_schema", node=ECConfig)
    cs.store(group="algo", name="ppo_schema", node=PPOConfig)
    cs.store(group="env", name="env_schema", node=EnvConfig)
    cs.store(group="logger", name="logger_schema", node=LoggerConfig)
    cs.store(group="evaluator", name="local_schema", node=LocalEvaluatorConfig)
    cs.store(group="evaluator", name="ray_schema", node=RayEvaluatorConfig)


SCHEMAS = {
    "algo": {"ga": GAConfig, "ec": ECConfig, "ppo": PPOConfig},
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
    try:
        plain = OmegaConf.create(OmegaConf.to_container(cfg, resolve=True))
    except InterpolationValidationError as err:  # its message echoes the value, which may be a secret (oc.env)
        raise ConfigError(
            f"{err.full_key}: its interpolation gives a value of the wrong type for the field (value not shown)"
        ) from None
    except OmegaConfBaseException as err:
        key = getattr(err, "full_key", None) or "config"
        raise ConfigError(f"{key}: {str(err).splitlines()[0]}") from None
    for group in ("algo", "evaluator"):
        node = plain.get(group)
        schema = _schema_of(group, node)
        what = "algo.kind ('ga', 'ec' or 'ppo')" if group == "algo" else "evaluator.name ('local' or 'ray')"
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
