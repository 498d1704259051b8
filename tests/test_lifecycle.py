"""The run lifecycle: a signal, wherever it lands between a recorded row and its checkpoint, leaves progress.csv
and the checkpoint holding the same rows."""

from __future__ import annotations

import os
import signal

import pytest

from spn_torchrl import checkpoint, lifecycle
from spn_torchrl.errors import RunInterrupted
from spn_torchrl.lifecycle import deferred_signals, open_run, signals_interrupt
from spn_torchrl.records import read_progress

META = {"format": 1, "task": "test"}


@pytest.mark.parametrize("when", ["pending before the row", "during the row"])
def test_a_signal_between_a_row_and_its_checkpoint_leaves_both_holding_the_same_rows(tmp_path, make_config, when):
    cfg = make_config("env=cartpole", "logger=csv")
    with pytest.raises(RunInterrupted), signals_interrupt(), open_run(cfg, tmp_path, "t", "ga", META, 2) as run:
        run.record({"generation": 1, "eval_return": 1.0}, step=1)
        run.save({"generation": 1})
        if when == "during the row":
            with deferred_signals():
                os.kill(os.getpid(), signal.SIGTERM)
                run.record({"generation": 2, "eval_return": 2.0}, step=2)
        else:  # a signal whose exception Python dropped in a finaliser: kept pending, raised by the next section
            lifecycle._pending.append(signal.SIGTERM)
        run.record({"generation": 2, "eval_return": 2.0}, step=2)
        run.save({"generation": 2})
    assert [r["generation"] for r in read_progress(tmp_path / "progress.csv")] == [1]
    assert [r["generation"] for r in checkpoint.load(tmp_path)["rows"]] == [1]


def test_a_non_finite_value_names_the_last_finite_checkpoint(tmp_path, make_config):
    import math

    import torch

    from spn_torchrl.errors import NonFiniteError

    cfg = make_config("env=cartpole", "logger.backend=none")
    with pytest.raises(NonFiniteError) as err, open_run(cfg, tmp_path, "t", "ga", META, 2) as run:
        run.require_finite("an episode return", torch.tensor([1.0, 2.0]), "generation 1")
        run.record({"generation": 1, "eval_return": 1.0}, step=1)
        run.save({"generation": 1})
        run.require_finite("an episode return", [torch.tensor([1.0, math.nan])], "generation 2")
    assert str(err.value) == (
        f"an episode return became NaN or infinite in generation 2: the run stopped there; {tmp_path} holds its last "
        "finite checkpoint (generation 1)"
    )
    assert [r["generation"] for r in checkpoint.load(tmp_path)["rows"]] == [1]
