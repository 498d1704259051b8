import os
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import CONF, ROOT
from hydra import compose, initialize_config_dir

from spn_torchrl.records import read_progress

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

SWEEP = [
    "env=cartpole",
    "algo=conn_ga",
    "algo.generations=1",
    "algo.population=10",
    "algo.elite_candidates=2",
    "algo.elite_episodes=5",
]


def multirun(sweep_dir: Path, *overrides: str) -> subprocess.CompletedProcess:
    """``python train.py -m ...`` in a subprocess, as a user would run a sweep."""
    env = {**os.environ, "WANDB_MODE": "offline", "WANDB_SILENT": "true"}
    cmd = [sys.executable, str(ROOT / "train.py"), "-m", f"hydra.sweep.dir={sweep_dir}", *SWEEP, *overrides]
    proc = subprocess.run(cmd, cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
    if proc.returncode != 0:
        pytest.fail(f"train.py -m failed ({proc.returncode}):\n{proc.stdout[-3000:]}\n{proc.stderr[-3000:]}")
    return proc


def test_multirun_writes_one_run_directory_per_job(tmp_path):
    multirun(tmp_path, "seed=0,1")
    runs = sorted(p.name for p in tmp_path.iterdir() if p.is_dir() and not p.name.startswith("."))
    assert runs == ["cartpole__conn_ga__0", "cartpole__conn_ga__1"]
    for name in runs:
        rows = read_progress(tmp_path / name / "progress.csv")
        assert [r["generation"] for r in rows] == [1]
        assert (tmp_path / name / "checkpoint.pt").exists()
        assert f"run {name} in " in (tmp_path / name / "train.log").read_text()  # no time suffix inside a sweep
    a, b = (read_progress(tmp_path / name / "progress.csv")[0] for name in runs)
    assert a["mean_fitness"] != b["mean_fitness"]  # two seeds, two runs
    assert (tmp_path / "multirun.yaml").exists()


def wandb_run_file(run_dir: Path) -> bytes:
    files = list(run_dir.glob("wandb/offline-run-*/*.wandb"))
    assert len(files) == 1, files
    return files[0].read_bytes()


def run_record_field(name: str, value: str) -> bytes:
    """``value`` as the protobuf field ``name`` of W&B's RunRecord (tag, length, bytes) in an offline run file."""
    from wandb.proto import wandb_internal_pb2

    number = wandb_internal_pb2.RunRecord.DESCRIPTOR.fields_by_name[name].number
    data = value.encode()
    assert len(data) < 128
    return bytes([number << 3 | 2, len(data)]) + data


@pytest.mark.skipif(
    __import__("importlib").util.find_spec("hydra_plugins.hydra_joblib_launcher") is None,
    reason="the parallel launcher needs the joblib extra: pip install -e '.[joblib]'",
)
def test_parallel_sweep_runs_share_a_wandb_group_and_are_named_per_seed(tmp_path):
    sweep_dir = tmp_path / "my_sweep"
    multirun(
        sweep_dir,
        "hydra/launcher=parallel",
        "hydra.launcher.n_jobs=2",
        "logger=wandb",
        "logger.mode=offline",
        "seed=0,1",
    )
    for seed in (0, 1):
        record = wandb_run_file(sweep_dir / f"cartpole__conn_ga__{seed}")
        assert run_record_field("run_group", "my_sweep") in record  # the sweep directory's name
        assert run_record_field("display_name", f"cartpole__conn_ga__{seed}") in record
        # a loky worker cannot spawn evaluator.processes workers: the job says so and evaluates in its own process
        assert "evaluating in this process" in (sweep_dir / f"cartpole__conn_ga__{seed}" / "train.log").read_text()


def launcher(name: str):
    with initialize_config_dir(config_dir=str(CONF), version_base=None):
        return compose(
            config_name="config", overrides=[f"hydra/launcher={name}"], return_hydra_config=True
        ).hydra.launcher


@pytest.mark.parametrize(
    "name,plugin,target",
    [
        ("parallel", "hydra_plugins.hydra_joblib_launcher", "JoblibLauncher"),
        ("slurm", "hydra_plugins.hydra_submitit_launcher", "SlurmLauncher"),
    ],
)
def test_launcher_presets_compose(name, plugin, target):
    pytest.importorskip(plugin, reason=f"hydra/launcher={name} needs its extra")
    cfg = launcher(name)
    assert cfg._target_.endswith(target)
    if name == "slurm":
        assert cfg.cpus_per_task >= 1 and cfg.timeout_min > 0 and cfg.partition is None
