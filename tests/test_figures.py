"""The report's learning-curve figures: what each curve draws. Fast: runs written by hand."""

import math

import matplotlib.pyplot as plt
import numpy as np
from synthetic_runs import write_run

from spn_torchrl.analysis.figures import _band
from spn_torchrl.analysis.runs import find_runs

NAN = math.nan


def test_a_ppo_curve_joins_its_evaluated_iterations_and_skips_the_nan_rows_between(tmp_path):
    returns = [[NAN, NAN, 10.0, NAN, NAN, 40.0], [NAN, NAN, 20.0, NAN, NAN, 60.0]]
    for seed, values in enumerate(returns):
        write_run(tmp_path, "swimmer", "Swimmer-v5", "dpn_ppo", seed, values, kind="ppo", total_env_steps=6000)
    runs = find_runs([tmp_path])
    fig, ax = plt.subplots()
    _band(ax, [1000, 2000, 3000, 4000, 5000, 6000], runs, "dpn_ppo", None)
    line = ax.get_lines()[0]
    np.testing.assert_array_equal(line.get_xdata(), [3000, 6000])
    np.testing.assert_array_equal(line.get_ydata(), [15.0, 50.0])
    plt.close(fig)
