"""The run contract under the probe of issue 44: one live run per directory, a refused run leaves the directory's
record as it was, a non-finite value ends the run in one sentence, the saved config is the resolved one (each case a
subprocess run of train.py with real processes, signals and files)."""

from __future__ import annotations

import contextlib
import csv
import os
import shlex
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch
import yaml
from conftest import ROOT, run_train, sigterm_after_first_checkpoint, train_command, wandb_exit_codes

from spn_torchrl import checkpoint
from spn_torchrl.records import read_progress

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

ONE = ["evaluator.processes=1", "torch_threads=1"]
BASE = ["env=cartpole", "algo.population=20", "algo.elite_candidates=2", "algo.elite_episodes=2", "seed=1", *ONE]
LONG = ["env=cartpole", "algo.generations=200", "algo.population=200", "algo.elite_candidates=2", "seed=1", *ONE]
PPO = ["algo=dpn_ppo", "algo.frames_per_batch=200", "algo.minibatch_size=50", "algo.epochs=2", "algo.eval_episodes=2"]


def last_line(proc: subprocess.CompletedProcess) -> str:
    return proc.stderr.strip().splitlines()[-1]


def record(run_dir: Path) -> dict[str, bytes]:
    """The bytes of every file of a run directory's config record and progress."""
    names = [".hydra/config.yaml", ".hydra/overrides.yaml", ".hydra/hydra.yaml", "progress.csv"]
    return {name: (run_dir / name).read_bytes() for name in names if (run_dir / name).exists()}


def start_live(run_dir: Path, *overrides: str) -> subprocess.Popen:
    """A long run in ``run_dir``, returned once its first checkpoint is on disk."""
    proc = subprocess.Popen(
        train_command(run_dir, *LONG, *overrides), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    deadline = time.time() + 120
    while not (run_dir / "checkpoint.pt").exists() and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)
    assert proc.poll() is None, proc.stderr.read().decode()
    return proc


def test_a_directory_belongs_to_one_live_run_and_a_killed_run_leaves_no_stuck_lock(tmp_path):
    live = start_live(tmp_path)
    try:
        before = record(tmp_path)
        for second in (["seed=2", "algo.generations=20"], ["resume=true"], []):
            proc = run_train(tmp_path, *LONG, *second, check=False)
            assert proc.returncode == 1 and "Traceback" not in proc.stderr
            assert last_line(proc) == (
                f"error: {tmp_path} is in use by a live run (process {live.pid}): "
                "wait for it to end, or use a new run directory"
            )
            assert record(tmp_path)[".hydra/config.yaml"] == before[".hydra/config.yaml"]
        assert yaml.safe_load((tmp_path / ".hydra/config.yaml").read_text())["seed"] == 1
    finally:
        live.send_signal(signal.SIGKILL)
        live.communicate(timeout=60)
    state = checkpoint.load(tmp_path)
    assert state["config"]["seed"] == 1
    # the kernel released the killed run's lock: the next run reaches the config contract
    proc = run_train(tmp_path, *LONG, "seed=2", "resume=true", check=False)
    assert last_line(proc).startswith(f"error: resume=true with a config that would change the results of {tmp_path}")


def test_two_identical_runs_do_not_log_every_row_twice(tmp_path):
    live = start_live(tmp_path)
    try:
        proc = run_train(tmp_path, *LONG, check=False)
        assert "is in use by a live run" in last_line(proc)
    finally:
        live.send_signal(signal.SIGTERM)
        live.communicate(timeout=60)
    assert live.returncode == 143
    run_train(tmp_path, *LONG[:1], "algo.generations=3", *LONG[2:], "resume=false", check=False)
    for path in tmp_path.glob("logs/*/scalars/**/*.csv"):
        steps = [line.split(",")[0] for line in path.read_text().splitlines()]
        assert len(steps) == len(set(steps)), path


@pytest.mark.parametrize(
    "second",
    [
        ["algo.generations=2", "seed=3"],  # a new run into a directory that holds one
        ["algo.generations=2", "seed=3", "resume=true"],  # a resume that would change the results
        ["algo.generations=1", "resume=true"],  # a shrinking resume
    ],
)
def test_a_refused_run_leaves_the_directorys_record_as_it_was(tmp_path, second):
    run_train(tmp_path, *BASE, "algo.generations=2")
    before = record(tmp_path)
    assert set(before) == {".hydra/config.yaml", ".hydra/overrides.yaml", ".hydra/hydra.yaml", "progress.csv"}
    proc = run_train(tmp_path, *BASE, *second, check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr and last_line(proc).startswith("error: ")
    assert record(tmp_path) == before


def test_a_users_directory_without_a_checkpoint_keeps_its_files(tmp_path):
    (tmp_path / ".hydra").mkdir(parents=True)
    (tmp_path / ".hydra/config.yaml").write_text("mine: true\n")
    (tmp_path / "progress.csv").write_text("generation,eval_return\n1,5.0\n")
    before = record(tmp_path)
    proc = run_train(tmp_path, *BASE, "algo.generations=1", check=False)
    assert "holds progress.csv but no checkpoint.pt" in last_line(proc)
    assert record(tmp_path) == before and not (tmp_path / ".hydra/overrides.yaml").exists()


def test_a_multirun_subdirectory_two_jobs_share_keeps_the_first_jobs_record(tmp_path):
    env = {**os.environ, "WANDB_MODE": "offline"}
    command = [sys.executable, str(ROOT / "train.py"), "-m", f"hydra.sweep.dir={tmp_path}", *BASE]
    subprocess.run([*command, "algo.generations=1,2"], cwd=ROOT, env=env, capture_output=True, timeout=600)
    (job,) = [p.parent for p in tmp_path.glob("*/progress.csv")]
    saved = yaml.safe_load((job / ".hydra/config.yaml").read_text())
    assert saved["algo"]["generations"] == 1 and len(read_progress(job / "progress.csv")) == 1
    assert "algo.generations=1" in (job / ".hydra/overrides.yaml").read_text()


def test_the_saved_config_is_the_resolved_one(tmp_path, monkeypatch):
    monkeypatch.setenv("MYSEED", "4")
    run_train(tmp_path, *BASE, "algo.generations=1", "seed=${oc.env:MYSEED}")
    saved = yaml.safe_load((tmp_path / ".hydra/config.yaml").read_text())
    assert saved["seed"] == 4 and "oc.env" not in (tmp_path / ".hydra/config.yaml").read_text()
    assert checkpoint.load(tmp_path)["config"]["seed"] == 4


def test_an_interpolation_of_the_wrong_type_is_one_sentence_that_hides_its_value(tmp_path, monkeypatch):
    monkeypatch.setenv("MYSECRET", "s3cr3t-value")
    proc = run_train(tmp_path, *BASE, "algo.generations=1", "seed=${oc.env:MYSECRET}", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr and "s3cr3t" not in proc.stderr + proc.stdout
    assert last_line(proc).startswith("error: seed: ")


@pytest.mark.parametrize("override", ["env.name=../../escaped", "run_name=a/b", "algo.name=.."])
def test_a_name_that_would_leave_the_run_directory_is_refused(tmp_path, override):
    run_dir = tmp_path / "a" / "b"
    proc = run_train(run_dir, *BASE, "algo.generations=1", override, check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    field = override.split("=")[0]
    assert last_line(proc).startswith(f"error: {field} must be a file name of letters, digits")
    assert sorted(p.name for p in tmp_path.rglob("*") if p.is_file()) in ([], ["train.log"])


@pytest.mark.parametrize(
    "method,what,sentence",
    [
        (
            ["algo=weights_ga", *BASE, "algo.generations=2", "algo.sigma=1e300"],
            "a genome of the population (algo.sigma=1e+300)",
            "generation 1: the run stopped there; no checkpoint was written",
        ),
        (
            [*PPO, "env=cartpole", "algo.total_env_steps=1000", "algo.lr_policy=1e30"],
            "the PPO loss",
            "iteration 1: the run stopped there; no checkpoint was written",
        ),
    ],
)
def test_a_non_finite_value_ends_the_run_in_one_sentence(tmp_path, method, what, sentence):
    proc = run_train(tmp_path, *method, check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert last_line(proc) == f"error: {what} became NaN or infinite in {sentence}"
    assert not (tmp_path / "progress.csv").exists()


def test_an_extended_ppo_run_writes_the_rows_of_a_straight_run(tmp_path):
    """2000 steps resumed to 4000 with eval_interval=3 write the rows of a straight 4000-step run, energy counts
    included: iteration 10, the end of the first segment, is not evaluated in either."""
    overrides = [*PPO, "env=cartpole", "algo.eval_interval=3", "seed=2", *ONE]
    straight, extended = tmp_path / "straight", tmp_path / "extended"
    run_train(straight, *overrides, "algo.total_env_steps=4000")
    run_train(extended, *overrides, "algo.total_env_steps=2000")
    run_train(extended, *overrides, "algo.total_env_steps=4000", "resume=true")
    timing = {"wall_time_s", "steps_per_s"}

    def rows(run_dir: Path) -> list[dict[str, str]]:  # the text of each cell: bit for bit, NaN equal to NaN
        with open(run_dir / "progress.csv", newline="") as f:
            return [{k: v for k, v in row.items() if k not in timing} for row in csv.DictReader(f)]

    assert len(rows(straight)) == 20
    assert rows(extended) == rows(straight)


def test_sigterm_under_the_ray_evaluator_ends_the_run_as_the_local_evaluator_does(tmp_path):
    """SIGTERM on the driver of a local Ray cluster after generation 3: exit 143, the resume line alone (Ray's C++
    handler would dump a stack and abort, rc 134), the W&B run closed with the exit code, a checkpoint to resume."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("WANDB_")}
    env.update(HOME=str(tmp_path), WANDB_SILENT="true")
    run_dir, stderr = tmp_path / "run", tmp_path / "stderr.txt"
    ray = [*BASE[:-2], "algo.generations=200", "torch_threads=1", "evaluator=ray", "evaluator.num_actors=1"]
    ray += ["evaluator.num_cpus=1", "logger=wandb"]
    with open(stderr, "wb") as err:
        proc = subprocess.Popen(train_command(run_dir, *ray), cwd=ROOT, env=env, stdout=subprocess.DEVNULL, stderr=err)
        deadline, log = time.time() + 300, run_dir / "train.log"  # a guard: Ray took 70 s to start under load
        while not (log.exists() and "gen 3/" in log.read_text()) and time.time() < deadline and proc.poll() is None:
            time.sleep(0.05)
        assert proc.poll() is None, stderr.read_text()
        before = stderr.stat().st_size  # Ray's start-up lines
        proc.send_signal(signal.SIGTERM)
        proc.wait(timeout=120)
    after = stderr.read_bytes()[before:].decode()
    assert proc.returncode == 143, after
    assert after.strip().splitlines() == [
        f"stopped: interrupted by SIGTERM; {run_dir} holds a consistent checkpoint, resume with: python train.py "
        f"{' '.join(ray)} hydra.run.dir={run_dir} resume=true"
    ]
    assert wandb_exit_codes(run_dir) == [143]
    assert checkpoint.load(run_dir)["generation"] >= 3


def closed_port() -> int:
    """A localhost TCP port nothing listens on (a W&B server that cannot be reached, without a network)."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


@pytest.mark.parametrize(
    "mode,key,sentence",
    [
        ("online", False, "error: logger.mode=online needs a W&B API key for {url} (WANDB_API_KEY, or the ~/.netrc "),
        ("online", True, "error: logger.mode=online but the W&B server {url} cannot be reached (127.0.0.1:"),
        ("auto", True, "logger.mode=auto: the W&B server {url} cannot be reached (127.0.0.1:"),
    ],
)
def test_wandb_without_a_server_is_decided_before_the_run_starts(tmp_path, mode, key, sentence):
    """logger=wandb with no key or no server: online is refused in one sentence before the run writes anything, auto
    says it logs offline and runs (W&B itself waited about 100 s, then raised CommError)."""
    url = f"http://127.0.0.1:{closed_port()}"
    env = {k: v for k, v in os.environ.items() if not k.startswith("WANDB_")}
    env.update(
        HOME=str(tmp_path), WANDB_SILENT="true", WANDB_BASE_URL=url, **({"WANDB_API_KEY": "k" * 40} if key else {})
    )
    run_dir = tmp_path / "run"
    proc = subprocess.run(
        train_command(run_dir, *BASE, "algo.generations=1", "logger=wandb", f"logger.mode={mode}"),
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=90,  # a guard against W&B's own wait
    )
    assert "Traceback" not in proc.stderr
    if mode == "online":
        assert proc.returncode == 1 and last_line(proc).startswith(sentence.format(url=url)), proc.stderr
        assert sorted(p.name for p in run_dir.iterdir()) == ["train.log"]  # no record, lock, env or W&B run
    else:
        assert proc.returncode == 0, proc.stderr
        assert sentence.format(url=url) in (run_dir / "train.log").read_text()
        assert list(run_dir.glob("wandb/offline-run-*/*.wandb"))


def test_sigint_before_the_first_checkpoint_says_there_is_none_and_quotes_the_path(tmp_path):
    """SIGINT once the run has started, long before its first generation ends, in a directory with spaces: the line
    says no checkpoint was written and its command, pasted into a shell, starts the run again in that directory."""
    run_dir = tmp_path / "my runs" / "a b"
    slow = [*LONG[:2], "algo.population=5000", *LONG[3:]]
    proc = subprocess.Popen(train_command(run_dir, *slow), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline, log = time.time() + 120, run_dir / "train.log"
    while not (log.exists() and f" in {run_dir}" in log.read_text()) and time.time() < deadline and proc.poll() is None:
        time.sleep(0.05)  # "run NAME in DIR": the run holds its directory, its handlers are in
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130 and not (run_dir / "checkpoint.pt").exists(), err
    line = err.decode().strip().splitlines()[-1]
    prefix = f"stopped: interrupted by SIGINT before the first checkpoint; {run_dir} holds none, start again with: "
    assert line.startswith(prefix), line
    command = shlex.split(line.removeprefix(prefix))
    assert command == ["python", "train.py", *slow, f"hydra.run.dir={run_dir}"]


def tool(*args: str) -> subprocess.CompletedProcess:
    """``python -m spn_torchrl.TOOL ARGS``, as a user runs it."""
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", *args], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)


def test_export_does_not_overwrite_the_runs_checkpoint(tmp_path):
    run_train(tmp_path, *BASE, "algo.generations=1")
    before = (tmp_path / "checkpoint.pt").read_bytes()
    for target in ("checkpoint.pt", "progress.csv", ".hydra/config.yaml"):
        proc = tool("spn_torchrl.export", str(tmp_path), str(tmp_path / target))
        assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert last_line(proc) == f"error: {tmp_path / target} is a file of the run in {tmp_path}: " + (
            "write the export to another path"
        )
    assert (tmp_path / "checkpoint.pt").read_bytes() == before
    assert tool("spn_torchrl.export", str(tmp_path), str(tmp_path / "elite.nir")).returncode == 0


def test_a_non_finite_ppo_level_is_refused_in_one_sentence(tmp_path):
    run_train(tmp_path / "run", *BASE, "algo.generations=1")
    proc = tool("spn_torchrl.report", str(tmp_path / "run"), "--ppo-level", "nan", "--out", str(tmp_path / "report"))
    assert proc.returncode == 1 and proc.stderr.strip() == "error: --ppo-level must be a finite return, got nan"
    assert not (tmp_path / "report").exists()


def test_play_on_a_run_without_a_finished_generation_says_so(tmp_path):
    """SIGTERM while generation 1's elite is re-evaluated (beside generation 2's population): the checkpoint holds
    generation 1's population, no elite yet."""
    returncode, _ = sigterm_after_first_checkpoint(tmp_path, *LONG[:2], "algo.population=3000", *LONG[3:])
    assert returncode == 143 and checkpoint.load(tmp_path)["elites"].shape[0] == 0
    proc = tool("spn_torchrl.play", str(tmp_path), "--episodes", "1")
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert last_line(proc) == (
        f"error: {tmp_path} holds no finished generation yet (the first elite's re-evaluation had not ended when it "
        "stopped): resume the run for at least one generation first"
    )


@pytest.mark.parametrize("kind", ["file", "dangling link", "below a file"])
def test_a_run_directory_that_is_a_file_or_a_dangling_link_is_one_sentence(tmp_path, kind):
    """Hydra created the directory itself and raised FileExistsError or OSError as a traceback; the file or link
    stays as it was."""
    thing = tmp_path / "thing"
    if kind == "dangling link":
        thing.symlink_to(tmp_path / "nowhere")
    else:
        thing.write_text("the user's\n")
    run_dir = thing / "run" if kind == "below a file" else thing
    proc = run_train(run_dir, *BASE, "algo.generations=1", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr + proc.stdout, proc.stderr
    problem = {
        "file": f"{thing} is a file, expected a directory",
        "dangling link": f"{thing} is a symbolic link to {tmp_path / 'nowhere'}, which does not exist: expected a "
        "directory",
        "below a file": f"{thing} is a file, expected a directory (to hold {run_dir})",
    }[kind]
    assert proc.stderr.strip() == f"error: hydra.run.dir={run_dir}: {problem}"
    if kind == "dangling link":
        assert os.readlink(thing) == str(tmp_path / "nowhere")
    else:
        assert thing.read_text() == "the user's\n"


def rewrite_checkpoint(run_dir: Path, change) -> bytes:
    """Apply ``change`` to the state in ``run_dir``'s checkpoint and save it; the damaged file's bytes."""
    path = run_dir / "checkpoint.pt"
    state = torch.load(path, weights_only=True)
    change(state)
    torch.save(state, path)
    return path.read_bytes()


@pytest.mark.parametrize(
    "change,problem",
    [
        (lambda s: s.pop("w1"), "no 'w1' entry"),
        (lambda s: s.update(elites=s["elites"].tolist()), "'elites' is a list, not a 2-dimensional tensor"),
        (lambda s: s.update(population=s["population"][:, :3]), "'population' has shape (20, 3), not 384 genes"),
        (lambda s: s.update(meta={**s["meta"], "env_id": None}), "'meta.env_id' is a NoneType"),
    ],
    ids=["missing", "list", "shape", "meta"],
)
def test_a_checkpoint_of_the_wrong_shapes_is_one_sentence_to_resume_play_and_export(tmp_path, change, problem):
    """A checkpoint that loads but whose entries are missing or of other types or shapes: resume, play and export
    each end in one sentence naming the file and the entry (they raised KeyError, AttributeError, ValueError), and
    the file is left as it was."""
    run_train(tmp_path, *BASE, "algo.generations=1")
    damaged = rewrite_checkpoint(tmp_path, change)
    sentence = f"error: {tmp_path / 'checkpoint.pt'} is a damaged spn_torchrl.ga/3 checkpoint ({problem}"
    procs = [
        run_train(tmp_path, *BASE, "algo.generations=2", "resume=true", check=False),
        tool("spn_torchrl.play", str(tmp_path), "--episodes", "1"),
        tool("spn_torchrl.export", str(tmp_path), str(tmp_path / "elite.nir")),
    ]
    for proc in procs:
        assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
        assert last_line(proc).startswith(sentence), proc.stderr
    assert (tmp_path / "checkpoint.pt").read_bytes() == damaged and not (tmp_path / "elite.nir").exists()


def test_a_ppo_checkpoint_whose_network_does_not_fit_is_one_sentence(tmp_path):
    """A PPO checkpoint whose actor holds other shapes than the config builds (load_state_dict's RuntimeError)."""
    run_train(tmp_path, *PPO, "env=cartpole", "algo.total_env_steps=200", *ONE)
    rewrite_checkpoint(tmp_path, lambda s: s.update(actor={k: v[..., :1] for k, v in s["actor"].items()}))
    proc = run_train(tmp_path, *PPO, "env=cartpole", "algo.total_env_steps=400", *ONE, "resume=true", check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert last_line(proc) == (
        f"error: {tmp_path / 'checkpoint.pt'} is a damaged spn_torchrl.ppo/2 checkpoint ('actor' does not fit the "
        "actor this config builds: RuntimeError): restore it from a copy, or use a new run directory"
    )


def catches(pid: int, signum: int) -> bool:
    """Whether process ``pid`` has a handler of its own for ``signum`` (/proc's SigCgt mask)."""
    with contextlib.suppress(OSError):
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("SigCgt:"):
                return bool(int(line.split()[1], 16) >> (signum - 1) & 1)
    return False


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_during_start_up_is_one_line(tmp_path, signum):
    """Ctrl-C (or SIGTERM) while train.py imports torch and Hydra composes, before the run began: one line and the
    signal's exit code, no traceback (a KeyboardInterrupt traceback from inside torch's imports before), and the run
    directory holds no run file."""
    proc = subprocess.Popen(
        train_command(tmp_path, *BASE), cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )
    deadline = time.time() + 60
    while not catches(proc.pid, signal.SIGTERM) and time.time() < deadline and proc.poll() is None:
        time.sleep(0.002)  # Python handles SIGTERM once train.py's first lines ran, seconds before its imports end
    proc.send_signal(signum)
    _, err = proc.communicate(timeout=120)
    name = signal.Signals(signum).name
    assert proc.returncode == 128 + signum and "Traceback" not in err, err
    assert err.strip() == f"stopped: interrupted by {name} while starting, before its run began; start it again"
    assert not (tmp_path / "checkpoint.pt").exists() and not (tmp_path / "progress.csv").exists()


def test_an_unknown_mujoco_gl_is_one_sentence_for_a_video_and_harmless_to_a_run(tmp_path):
    """MUJOCO_GL=bogus: MuJoCo's import raised RuntimeError in every command (TorchRL's envs import it); now a run,
    which renders nothing, runs, and play --video refuses the value in one sentence before its replay."""
    env = {**os.environ, "MUJOCO_GL": "bogus", "PYTHONPATH": str(ROOT), "WANDB_MODE": "disabled"}
    ran = subprocess.run(
        train_command(tmp_path, *BASE, "algo.generations=1"), cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert ran.returncode == 0, ran.stderr
    cmd = [sys.executable, "-m", "spn_torchrl.play", str(tmp_path), "--episodes", "1", "--video", "v.mp4"]
    proc = subprocess.run(cmd, cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 1 and proc.stderr.strip() == (
        "error: MUJOCO_GL='bogus' is not a MuJoCo rendering backend: set MUJOCO_GL=egl or MUJOCO_GL=osmesa, or "
        "unset it to try both"
    )
    assert not (tmp_path / "v.mp4").exists()


@pytest.fixture
def silent_server():
    """A localhost URL whose TCP connects hang: a listener whose accept queue is full drops new SYNs."""
    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(0)
    port = server.getsockname()[1]
    fillers = []
    for _ in range(4):
        sock = socket.socket()
        sock.setblocking(False)
        with contextlib.suppress(BlockingIOError):
            sock.connect(("127.0.0.1", port))
        fillers.append(sock)
    yield f"http://127.0.0.1:{port}"
    for sock in [*fillers, server]:
        sock.close()


def test_auto_mode_with_a_key_and_a_silent_server_logs_offline_after_the_probes_bound(tmp_path, silent_server):
    """A W&B server that never answers (W&B itself waited about 100 s, then raised CommError): the probe gives up
    after its 3 s, the run logs offline and says why, and the whole run ends within a guard far below W&B's wait."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("WANDB_")}
    env.update(HOME=str(tmp_path), WANDB_SILENT="true", WANDB_BASE_URL=silent_server, WANDB_API_KEY="k" * 40)
    run_dir = tmp_path / "run"
    proc = subprocess.run(
        train_command(run_dir, *BASE, "algo.generations=1", "logger=wandb", "logger.mode=auto"),
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=90,
    )
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    port = silent_server.rsplit(":", 1)[1]
    log = (run_dir / "train.log").read_text()
    assert f"the W&B server {silent_server} cannot be reached (127.0.0.1:{port}: no answer within 3 s)" in log
    assert list(run_dir.glob("wandb/offline-run-*/*.wandb"))


def without_root_override(cmd: list[str]) -> list[str]:
    """``cmd`` under permission bits: as root, without the capabilities that write through them (setpriv)."""
    if os.geteuid() != 0:
        return cmd
    return ["setpriv", "--bounding-set=-dac_override,-dac_read_search,-fowner", *cmd]


@pytest.mark.parametrize("below", ["", "sub/run"], ids=["the directory", "a folder above"])
def test_a_read_only_run_directory_is_one_sentence(tmp_path, below):
    """A ``hydra.run.dir`` that is (or lies under) a read-only directory: one sentence before Hydra writes (its
    logging's PermissionError before), and the directory as it was."""
    read_only = tmp_path / "ro"
    read_only.mkdir()
    (read_only / "mine.txt").write_text("the user's\n")
    read_only.chmod(0o555)
    run_dir = read_only / below if below else read_only
    try:
        proc = subprocess.run(
            without_root_override(train_command(run_dir, *BASE)), cwd=ROOT, capture_output=True, text=True, timeout=300
        )
    finally:
        read_only.chmod(0o755)
    held = f" (to hold {run_dir})" if below else ""
    assert proc.returncode == 1 and proc.stderr.strip() == (
        f"error: hydra.run.dir={run_dir}: {read_only} is not writable by this user{held}: expected a directory it "
        "can write"
    ), proc.stderr
    assert sorted(p.name for p in read_only.iterdir()) == ["mine.txt"]
