"""``python -m spn_torchrl.play`` on tiny real runs: replay, errors, video, pictures."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import torch

from spn_torchrl.errors import SpnError
from spn_torchrl.records import read_progress
from spn_torchrl.tools.elite import load_elite
from spn_torchrl.tools.play import find_gl_backend, replay, run_episode, summary

pytestmark = pytest.mark.slow  # end-to-end runs in a subprocess

ROOT = Path(__file__).resolve().parents[1]


def play(*args: str) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "spn_torchrl.play", *map(str, args)]
    return subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)


def test_replay_is_deterministic_and_matches_the_run(cartpole_run):
    elite = load_elite(cartpole_run)
    assert elite.generation == 2
    first, second = replay(elite, 4, seed=3), replay(elite, 4, seed=3)
    assert torch.equal(first.returns, second.returns) and torch.equal(first.spikes, second.spikes)
    assert (first.returns > 0).all() and torch.equal(first.returns, first.steps.float())  # CartPole: 1 per step
    last = read_progress(cartpole_run / "progress.csv")[-1]
    assert summary(elite, first)["mask_density"] == pytest.approx(last["mask_density"])
    assert torch.equal(load_elite(cartpole_run, 1).genome, elite.elites[0])


def test_episode_trace_spikes_match_the_policy(cartpole_run):
    elite = load_elite(cartpole_run)
    trace = run_episode(elite, seed=0)
    steps = trace.observations.shape[0]
    assert trace.spikes.shape == (steps, elite.cfg.algo.snn.time_steps, elite.cfg.algo.snn.hidden)
    assert trace.episode_return == steps
    elite.spn.set_genomes(elite.genome[None].expand(steps, -1))
    actions, counts = elite.spn(trace.observations)
    assert torch.equal(actions, trace.actions)
    assert torch.equal(counts, trace.spikes.sum((1, 2)))


def test_play_prints_replay(cartpole_run):
    done = play(cartpole_run, "--episodes", "3", "--seed", "1")
    assert done.returncode == 0, done.stderr
    assert "returns over 3 episodes (seed 1)" in done.stdout
    assert "hidden spike rate" in done.stdout and "mask density" in done.stdout


@pytest.mark.parametrize(
    "setup, args, message",
    [
        ("missing", [], "does not exist"),
        ("corrupt", [], "not a readable spn_torchrl checkpoint"),
        ("copy", ["--generation", "7"], "--generation must be in [1, 2]"),
        ("copy", ["--episodes", "0"], "--episodes must be >= 1"),
    ],
)
def test_play_errors_are_one_sentence(cartpole_run, tmp_path, setup, args, message):
    run_dir = tmp_path / "run"
    if setup != "missing":
        shutil.copytree(cartpole_run, run_dir)
    if setup == "corrupt":
        (run_dir / "checkpoint.pt").write_bytes(b"not a checkpoint")
    done = play(run_dir, *args)
    assert done.returncode != 0
    assert message in done.stderr and "Traceback" not in done.stderr
    assert len([line for line in done.stderr.splitlines() if line.startswith("error:")]) == 1


def test_pictures(cartpole_run, tmp_path):
    pytest.importorskip("matplotlib")
    from PIL import Image

    done = play(cartpole_run, "--episodes", "1", "--pictures", tmp_path)
    assert done.returncode == 0, done.stderr
    raster, grid, gif = tmp_path / "spike_raster_gen2.png", tmp_path / "connectivity.png", tmp_path / "connectivity.gif"
    for path in (raster, grid, gif):
        assert path.stat().st_size > 0
    with Image.open(gif) as image:
        assert image.n_frames == 2  # one frame per generation


def gl_backend_or_skip(env_id: str) -> str:
    try:
        return find_gl_backend(env_id)
    except SpnError as err:
        pytest.skip(f"no OpenGL backend renders offscreen here: {err}")


def test_video_of_halfcheetah(halfcheetah_run, tmp_path):
    imageio = pytest.importorskip("imageio")
    pytest.importorskip("imageio_ffmpeg")
    gl_backend_or_skip("HalfCheetah-v5")
    video = tmp_path / "cheetah.mp4"
    done = play(halfcheetah_run, "--episodes", "1", "--video", video, "--max-steps", "120")
    assert done.returncode == 0, done.stderr
    frames = imageio.mimread(video, memtest=False)
    assert len(frames) == 120
    for frame in frames[0], frames[60], frames[-1]:  # the tracking camera keeps the robot in view
        assert frame.ndim == 3 and frame.shape[2] == 3
        r, g, b = (frame[..., i].astype(int) for i in range(3))
        robot = (r > g + 30) & (g > b + 10)  # its tan and pink bodies; the floor is black and pale green
        assert robot.sum() > 200, "no robot in the frame"


def test_video_without_backend_is_one_sentence(halfcheetah_run, tmp_path, monkeypatch):
    pytest.importorskip("imageio_ffmpeg")
    monkeypatch.setenv("MUJOCO_GL", "glfw")  # a window-system backend: cannot work without a display
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    done = play(halfcheetah_run, "--episodes", "1", "--video", tmp_path / "x.mp4")
    assert done.returncode != 0
    assert "cannot render HalfCheetah-v5 offscreen" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "x.mp4").exists()
