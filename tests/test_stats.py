"""Welch's t-test from summary statistics and the functions under it, against known values."""

import math

import pytest

from spn_torchrl.analysis.stats import betainc, one_value, p_text, paired, sample_sd, t_cdf, verdict, welch


@pytest.mark.parametrize(
    "a, b, x, expected",
    [
        (1.0, 1.0, 0.3, 0.3),  # uniform
        (2.0, 3.0, 0.4, 0.5248),  # binomial sum: sum_{j=2..4} C(4,j) 0.4^j 0.6^(4-j)
        (3.0, 1.0, 0.7, 0.7**3),  # I_x(a, 1) = x^a
        (1.0, 4.0, 0.2, 1 - 0.8**4),  # I_x(1, b) = 1 - (1-x)^b
        (0.5, 0.5, 0.3, 2 / math.pi * math.asin(math.sqrt(0.3))),  # arcsine law
        (50.0, 50.0, 0.5, 0.5),  # symmetry
        (7.5, 0.5, 0.9, 0.21624836513726642),  # scipy.special.betainc, computed once outside the project
        (200.0, 0.5, 0.99, 0.04509410713707966),  # idem
        (5.0, 0.5, 0.0, 0.0),
        (5.0, 0.5, 1.0, 1.0),
    ],
)
def test_betainc_known_values(a, b, x, expected):
    assert betainc(a, b, x) == pytest.approx(expected, abs=1e-12)


def test_betainc_rejects_out_of_range():
    with pytest.raises(ValueError):
        betainc(0.0, 1.0, 0.5)
    with pytest.raises(ValueError):
        betainc(1.0, 1.0, 1.5)


@pytest.mark.parametrize(
    "t, df, expected",
    [
        (1.0, 1, 0.75),  # Cauchy: 1/2 + atan(1)/pi
        (1.5, 2, 0.5 + 1.5 / (2 * math.sqrt(2 + 1.5**2))),  # df = 2 closed form
        (-1.5, 2, 0.5 - 1.5 / (2 * math.sqrt(2 + 1.5**2))),
        (0.0, 7, 0.5),
        (2.228138851986, 10, 0.975),  # the table's 97.5% quantile of t(10)
        (12.7062047362, 1, 0.975),  # of t(1)
        (1.959963985, 1e7, 0.975),  # t(inf) = the normal
    ],
)
def test_t_cdf_known_values(t, df, expected):
    assert t_cdf(t, df) == pytest.approx(expected, abs=1e-7)


def test_welch_matches_a_hand_computation():
    # sample 1: mean 10, sd 2, n 5; sample 2: mean 12, sd 3, n 10
    v1, v2 = 4 / 5, 9 / 10
    t = -2 / math.sqrt(v1 + v2)
    df = (v1 + v2) ** 2 / (v1**2 / 4 + v2**2 / 9)
    test = welch(10, 2, 5, 12, 3, 10)
    assert test.t == pytest.approx(t) and test.df == pytest.approx(df)
    assert test.p == pytest.approx(2 * t_cdf(t, df))
    # scipy.stats.ttest_ind_from_stats(10, 2, 5, 12, 3, 10, equal_var=False), computed once outside the project
    assert test.p == pytest.approx(0.15194869210365436, abs=1e-12)


def test_welch_constant_samples():
    assert welch(500, 0, 10, 500, 0, 10).p == 1.0
    assert welch(499, 0, 10, 500, 0, 10).p == 0.0
    with pytest.raises(ValueError):
        welch(1, 1, 1, 2, 1, 10)


def test_one_value_against_a_sample_is_the_prediction_interval_test():
    # at the edge of the 95% prediction interval of a sample of 10 (mean 10, sd 2): 2.262157 is t(9)'s 97.5% quantile
    edge = 10 + 2.262157163 * 2 * math.sqrt(1 + 1 / 10)
    assert one_value(edge, 10, 2, 10).p == pytest.approx(0.05, abs=1e-8)
    low = one_value(4, 10, 2, 10)
    assert low.df == 9 and low.diff == -6 and low.t == pytest.approx(-3 / math.sqrt(1.1))
    assert verdict(low).startswith("lower than the paper, p = 0.0")
    assert one_value(500, 500, 0, 10).p == 1.0 and one_value(499, 500, 0, 10).p == 0.0
    with pytest.raises(ValueError):
        one_value(1, 1, 1, 1)


def test_paired_is_the_one_sample_test_of_the_differences():
    # differences c + (-2, -1, 0, 1, 2): sd sqrt(2.5), se sqrt(0.5); 2.776445105 is t(4)'s 97.5% quantile
    c = 2.776445105 * math.sqrt(0.5)
    edge = paired([c - 2, c - 1, c, c + 1, c + 2])
    assert edge.df == 4 and edge.t == pytest.approx(2.776445105) and edge.p == pytest.approx(0.05, abs=1e-8)
    assert paired([3.0, 3.0, 3.0]).p == 0.0 and paired([0.0, 0.0]).p == 1.0
    with pytest.raises(ValueError):
        paired([1.0])


def test_verdict_sentences():
    assert verdict(welch(100, 10, 10, 101, 10, 10)) == "consistent with the paper (p = 0.83)"  # scipy: 0.8259
    low = welch(50, 5, 10, 100, 5, 10)
    assert verdict(low) == "lower than the paper, p < 0.001"
    assert verdict(welch(110, 10, 10, 100, 10, 10)).startswith("higher than the paper, p = 0.0")
    assert p_text(0.0021) == "p = 0.0021" and p_text(0.31) == "p = 0.31"


def test_sample_sd_from_population_sd():
    values = [1.0, 2.0, 4.0, 7.0]
    mean = sum(values) / 4
    pop = math.sqrt(sum((v - mean) ** 2 for v in values) / 4)
    assert sample_sd(pop, 4) == pytest.approx(math.sqrt(sum((v - mean) ** 2 for v in values) / 3))
