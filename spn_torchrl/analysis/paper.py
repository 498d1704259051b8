"""The paper's published figures, typed in, each with where it comes from (for the reproduction report).

Sources: ``/work/shared/SPEC.md`` "Published results" (the authors' logs: 10 seeds, generation 100), and the
paper's tables (``paper/spn_ga_paper.tex``): Table 1 (label ``ratio``, data efficiency), Table 2 (``inference``),
Table 3 (``optim``), Table 4 (``number``, forward and backward passes). Tasks are keyed by the project's
``env.name``, methods by ``algo.name``. The paper ran Gym v2 tasks; the project runs Gymnasium v5.
"""

from __future__ import annotations

from dataclasses import dataclass

SEEDS = 10  # "We conducted 10 independent runs with different random seeds for all experiments" (Sec. 4.2)
GENERATIONS = 100  # G = 100 (Sec. 4.2, Implement Details)
PPO_STEPS = 1_000_000  # DPN-PPO ran 1e6 env steps (Sec. 4.2, Appendix)
CARTPOLE_LIMIT = 500.0  # "reached the upper limit return of 500" (Sec. 5.1.1)
CARTPOLE_MEAN_AT_LIMIT_BY = 50  # SPEC.md: "500 (mean reaches 500 by gen 50)"


@dataclass(frozen=True)
class Final:
    """A method's return at generation 100: mean and std over the paper's 10 seeds.

    The std is the population one (ddof=0): recomputing it from the authors' per-seed logs gives exactly the
    published figure only with ddof=0 (e.g. HalfCheetah Connections-GA 771.57).
    """

    mean: float
    std: float
    n: int = SEEDS


# SPEC.md "Published results" (authors' logs, mean over 10 seeds at generation 100, +- std over seeds)
FINAL: dict[tuple[str, str], Final] = {
    ("cartpole", "conn_ga"): Final(500.0, 0.0),  # SPEC.md: CartPole-v1 Connections-GA 500
    ("halfcheetah", "conn_ga"): Final(2759.0, 772.0),  # SPEC.md: 2759 +- 772
    ("halfcheetah", "weights_ga"): Final(2421.0, 936.0),  # SPEC.md: 2421 +- 936
    ("swimmer", "conn_ga"): Final(222.0, 87.0),  # SPEC.md: 222 +- 87
    ("swimmer", "weights_ga"): Final(18.6, 5.4),  # SPEC.md: 18.6 +- 5.4
    ("humanoidstandup", "conn_ga"): Final(150800.0, 9072.0),  # SPEC.md: 150800 +- 9072
    ("humanoidstandup", "weights_ga"): Final(157048.0, 7889.0),  # SPEC.md: 157048 +- 7889
}

# The PPO level R: DPN-PPO's return after 1e6 env steps (Table 1 column R; SPEC.md "PPO level R")
PPO_LEVEL: dict[str, float] = {"halfcheetah": 2544.64, "swimmer": 107.52, "humanoidstandup": 115722.54}

# First generation (1-based) of the authors' logged mean curve at R (SPEC.md "first generation at R")
FIRST_GENERATION_AT_R: dict[str, int] = {"halfcheetah": 61, "swimmer": 19, "humanoidstandup": 5}


@dataclass(frozen=True)
class Efficiency:
    """Table 1: G generations to reach R, E = G * A env steps (A = 3e5), gamma = E / 1e6."""

    G: int
    E: float
    gamma: float


# Table 1 (label "ratio"); its G is one less than the logs' first generation at R on Swimmer and HumanoidStandup
TABLE1: dict[str, Efficiency] = {
    "halfcheetah": Efficiency(61, 1.83e7, 18.3),
    "swimmer": Efficiency(18, 5.4e6, 5.4),
    "humanoidstandup": Efficiency(4, 1.2e6, 1.2),
}


@dataclass(frozen=True)
class Ratio:
    """A row of Table 2 or 3: DPN/PPO energy, SPN/GA energy (pJ) and the printed ratio."""

    dpn: float
    spn: float
    ratio: float


# Table 2 (label "inference"): E_infer_DPN, E_infer_SPN (pJ per env step), ratio
TABLE2: dict[str, Ratio] = {
    "halfcheetah": Ratio(6.77e3, 5.2e3, 1.3),
    "swimmer": Ratio(2.94e3, 2.41e3, 1.2),
    "humanoidstandup": Ratio(1.16e5, 1.1e5, 1.1),
}

# Table 3 (label "optim"): E_optim_PPO, E_optim_GA (pJ, GA up to R), ratio
TABLE3: dict[str, Ratio] = {
    "halfcheetah": Ratio(6.16e11, 9.52e10, 6.5),
    "swimmer": Ratio(2.85e11, 1.3e10, 21.9),
    "humanoidstandup": Ratio(1.16e13, 1.32e11, 87.9),
}

# Table 4 (label "number"): PPO's passes per network (policy and value alike) over 1e6 steps; GA's forward
# passes (= E of Table 1), no backward pass
TABLE4_PPO_FORWARD = 2.6e7
TABLE4_PPO_BACKWARD = 2.5e7
TABLE4_GA_FORWARD: dict[str, float] = {"halfcheetah": 1.83e7, "swimmer": 5.4e6, "humanoidstandup": 1.2e6}

# Sec. 5.2: Connections-GA "achieved a higher average return on HalfCheetah-v2 and Swimmer-v2 compared to
# SPN-Weights-GA ... a comparable average return on HumanoidStandup-v2"; Weights-GA "could not achieve the
# same performance level as DPN-Weights-PPO on HalfCheetah-v2 and Swimmer-v2"
CONNECTIONS_BEAT_WEIGHTS = ("halfcheetah", "swimmer")
CONNECTIONS_MATCH_WEIGHTS = ("humanoidstandup",)
WEIGHTS_BELOW_R = ("halfcheetah", "swimmer")
# Sec. 5.3: "the learning curve of SPN-Connections-PPO did not converge, and its average return even decreased"
CONN_PPO_TASKS = ("halfcheetah", "swimmer", "humanoidstandup")

TASK_TITLES = {
    "cartpole": "CartPole",
    "halfcheetah": "HalfCheetah",
    "swimmer": "Swimmer",
    "humanoidstandup": "HumanoidStandup",
}
METHOD_TITLES = {
    "conn_ga": "Connections-GA",
    "weights_ga": "Weights-GA",
    "dpn_ppo": "DPN-PPO",
    "conn_ppo": "Connections-PPO",
}
