"""Welch's t-test from summary statistics (and one value's test against a sample), with the Student t CDF from the
regularized incomplete beta function.

Plain ``math``: no scipy. ``betainc`` is the continued fraction of Numerical Recipes (Lentz's method), accurate
to about 1e-12 for the degrees of freedom a seed count gives.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

ALPHA = 0.05
_EPS = 1e-15
_TINY = 1e-300


def _beta_fraction(x: float, a: float, b: float, max_iter: int = 500) -> float:
    """The continued fraction of I_x(a, b) (converges fast for x < (a + 1) / (a + b + 2))."""
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > _TINY else _TINY)
    h = d
    for m in range(1, max_iter + 1):
        m2 = 2 * m
        for aa in (m * (b - m) * x / ((qam + m2) * (a + m2)), -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))):
            d = 1.0 + aa * d
            d = 1.0 / (d if abs(d) > _TINY else _TINY)
            c = 1.0 + aa / c
            c = c if abs(c) > _TINY else _TINY
            h *= d * c
        if abs(d * c - 1.0) < _EPS:
            return h
    raise ArithmeticError(f"betainc({a}, {b}, {x}) did not converge")


def betainc(a: float, b: float, x: float) -> float:
    """The regularized incomplete beta function I_x(a, b), for a, b > 0 and 0 <= x <= 1."""
    if a <= 0 or b <= 0 or not 0.0 <= x <= 1.0:
        raise ValueError(f"betainc needs a, b > 0 and 0 <= x <= 1, got a={a}, b={b}, x={x}")
    if x in (0.0, 1.0):
        return x
    log_front = math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x) + b * math.log1p(-x)
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(log_front) * _beta_fraction(x, a, b) / a
    return 1.0 - math.exp(log_front) * _beta_fraction(1.0 - x, b, a) / b


def t_cdf(t: float, df: float) -> float:
    """P(T <= t) for Student's t with ``df`` (> 0, not necessarily whole) degrees of freedom."""
    if df <= 0:
        raise ValueError(f"degrees of freedom must be positive, got {df}")
    if math.isinf(t):
        return 1.0 if t > 0 else 0.0
    tail = 0.5 * betainc(df / 2.0, 0.5, df / (df + t * t))
    return 1.0 - tail if t > 0 else tail


@dataclass(frozen=True)
class TTest:
    """A two-sided t-test of sample 1 (or one value) against sample 2."""

    t: float
    df: float
    p: float
    diff: float  # mean 1 (or the value) - mean 2


def _t_test(diff: float, se: float, df: float) -> TTest:
    """The two-sided test of ``diff`` with standard error ``se``; a zero ``se`` gives p = 1 for no difference, else 0."""
    if se == 0:
        return TTest(0.0 if diff == 0 else math.copysign(math.inf, diff), df, 1.0 if diff == 0 else 0.0, diff)
    t = diff / se
    return TTest(t, df, 2.0 * t_cdf(-abs(t), df), diff)


def welch(mean1: float, sd1: float, n1: int, mean2: float, sd2: float, n2: int) -> TTest:
    """Welch's t-test from means, sample standard deviations (ddof=1) and sizes (each at least 2).

    Two equal constant samples give p = 1; two different constant samples p = 0.
    """
    if n1 < 2 or n2 < 2:
        raise ValueError(f"Welch's test needs at least 2 values per sample, got {n1} and {n2}")
    v1, v2 = sd1 * sd1 / n1, sd2 * sd2 / n2
    if v1 + v2 == 0:
        return _t_test(mean1 - mean2, 0.0, math.inf)
    df = (v1 + v2) ** 2 / ((v1 * v1 / (n1 - 1) if v1 else 0.0) + (v2 * v2 / (n2 - 1) if v2 else 0.0))
    return _t_test(mean1 - mean2, math.sqrt(v1 + v2), df)


def paired(differences: Sequence[float]) -> TTest:
    """The paired two-sided t-test of the per-item differences of two samples (at least 2): their mean over
    its standard error, n - 1 degrees of freedom."""
    n = len(differences)
    if n < 2:
        raise ValueError(f"a paired t-test needs at least 2 differences, got {n}")
    mean = math.fsum(differences) / n
    sd = math.sqrt(math.fsum((d - mean) ** 2 for d in differences) / (n - 1))
    return _t_test(mean, sd / math.sqrt(n), n - 1)


def one_value(value: float, mean: float, sd: float, n: int) -> TTest:
    """The t-test of one new value against a sample of ``n`` (at least 2) with ``mean`` and sample std ``sd``
    (ddof=1): t = (value - mean) / (sd * sqrt(1 + 1/n)) with n - 1 degrees of freedom, the prediction interval's
    test. A value equal to a constant sample's mean gives p = 1, any other p = 0."""
    if n < 2:
        raise ValueError(f"a value's t-test needs a sample of at least 2, got {n}")
    return _t_test(value - mean, sd * math.sqrt(1.0 + 1.0 / n), n - 1)


def sample_sd(population_sd: float, n: int) -> float:
    """The sample (ddof=1) standard deviation of ``n`` values from their population (ddof=0) one."""
    return population_sd * math.sqrt(n / (n - 1))


def p_text(p: float) -> str:
    """A p-value as a report prints it: ``p = 0.31``, ``p = 0.002``, ``p < 0.001``."""
    if p < 0.001:
        return "p < 0.001"
    return f"p = {p:.2g}"


def verdict(test: TTest, than: str = "the paper", alpha: float = ALPHA) -> str:
    """One plain sentence part: ``consistent with the paper (p = 0.31)`` or ``lower than the paper, p = 0.002``."""
    if test.p >= alpha:
        return f"consistent with {than} ({p_text(test.p)})"
    return f"{'higher' if test.diff > 0 else 'lower'} than {than}, {p_text(test.p)}"
