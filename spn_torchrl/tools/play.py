"""Watch an evolved SPN: ``python -m spn_torchrl.play RUN_DIR [--generation G] [--episodes E] [--seed S]
[--video PATH] [--pictures DIR]``.

Replays a generation's elite (default: the last) on the run's task, rebuilt from the checkpoint's config and
fixed weights, and prints its returns, hidden spike rate, mask density (and inference energy per step where
``spn_torchrl.analysis.energy`` exists). ``--video`` writes an MP4 of one episode (MuJoCo renders offscreen through
``MUJOCO_GL``: ``egl`` or ``osmesa``); ``--pictures`` draws the spike raster and the connectivity across
generations (see :mod:`spn_torchrl.tools.pictures`).
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import gymnasium as gym
import numpy as np
import torch

from spn_torchrl.analysis.energy import inference_energy
from spn_torchrl.envs import make_batched_env
from spn_torchrl.errors import SpnError, require
from spn_torchrl.evaluation.rollout import Episodes, PopulationEvaluator, spike_rate
from spn_torchrl.snn import neurons
from spn_torchrl.snn.observations import normalize
from spn_torchrl.snn.policies import mask_density
from spn_torchrl.tools.elite import Elite, load_elite

GL_BACKENDS = ("egl", "osmesa")


@dataclass
class Trace:
    """One episode of a single env, step by step."""

    observations: torch.Tensor  # [S, n], the env's observations (the SPN saw them normalised where the run did)
    actions: torch.Tensor  # [S, m] or [S]
    spikes: torch.Tensor  # [S, T', h] hidden spikes of every simulation step
    episode_return: float
    frames: list[np.ndarray] = field(default_factory=list)


def replay(elite: Elite, episodes: int, seed: int) -> Episodes:
    """``episodes`` episodes of the elite (one batched env, the elite repeated, with its observation
    normalisation), seeded by ``seed``."""
    env = make_batched_env(elite.spec.env_id, episodes, backend=elite.cfg.env.backend, threads=elite.cfg.env.threads)
    evaluator = PopulationEvaluator(env, elite.spn, elite.spec.max_episode_steps)
    try:
        return evaluator(elite.genome[None].expand(episodes, -1), seed, elite.obs_norm)
    finally:
        evaluator.close()


def hidden_spike_train(elite: Elite, observation: torch.Tensor) -> torch.Tensor:
    """Hidden spikes [T', h] of one environment step (the LIF part of :func:`neurons.spn_dynamics`)."""
    snn = elite.cfg.algo.snn
    seen = normalize(observation[None], elite.obs_norm)[0]
    return neurons.lif_spikes(elite.weights[0] @ seen, snn.time_steps, snn.decay, snn.v_threshold)


def make_render_env(env_id: str) -> gym.Env:
    """The task rendering RGB frames, through the model's tracking camera ("track") where it has one, so that
    a walker stays in view (MuJoCo's default free camera does not follow it)."""
    try:
        return gym.make(env_id, render_mode="rgb_array", camera_name="track")
    except (TypeError, ValueError):  # no camera_name argument (not MuJoCo) or no such camera
        return gym.make(env_id, render_mode="rgb_array")


def run_episode(elite: Elite, seed: int, render: bool = False, max_steps: int | None = None) -> Trace:
    """One episode (cut at ``max_steps`` if given) on a plain Gymnasium env, recording observations, actions,
    hidden spikes (and frames)."""
    elite.spn.set_genomes(elite.genome[None])
    elite.spn.set_observation_norm(elite.obs_norm)
    env = make_render_env(elite.spec.env_id) if render else gym.make(elite.spec.env_id)
    observations, actions, spikes, frames = [], [], [], []
    total = 0.0
    try:
        obs, _ = env.reset(seed=seed)
        for _ in range(min(max_steps or elite.spec.max_episode_steps, elite.spec.max_episode_steps)):
            if render:
                frames.append(env.render())
            o = torch.as_tensor(obs, dtype=torch.float32)
            action, _ = elite.spn(o[None])
            observations.append(o)
            actions.append(action[0])
            spikes.append(hidden_spike_train(elite, o))
            obs, reward, terminated, truncated, _ = env.step(action[0].numpy())
            total += float(reward)
            if terminated or truncated:
                break
    finally:
        env.close()
    return Trace(torch.stack(observations), torch.stack(actions), torch.stack(spikes), total, frames)


def find_gl_backend(env_id: str) -> str:
    """A ``MUJOCO_GL`` value that renders ``env_id`` offscreen here (tried in a subprocess), or a clear error."""
    unknown = os.environ.get("SPN_TORCHRL_UNKNOWN_MUJOCO_GL")  # set aside by the package (MuJoCo refuses it)
    if unknown is not None:
        raise SpnError(
            f"MUJOCO_GL={unknown!r} is not a MuJoCo rendering backend: set MUJOCO_GL=egl or MUJOCO_GL=osmesa, or "
            "unset it to try both"
        )
    candidates = [os.environ["MUJOCO_GL"]] if os.environ.get("MUJOCO_GL") else list(GL_BACKENDS)
    probe = f"import gymnasium as g; e = g.make({env_id!r}, render_mode='rgb_array'); e.reset(seed=0); e.render()"
    reasons = []
    for backend in candidates:
        env = dict(os.environ, MUJOCO_GL=backend)
        if backend in GL_BACKENDS:
            env["PYOPENGL_PLATFORM"] = backend
        done = subprocess.run([sys.executable, "-c", probe], env=env, capture_output=True, text=True, timeout=120)
        if done.returncode == 0:
            return backend
        lines = [line for line in done.stderr.strip().splitlines() if line.strip()]
        reasons.append(f"MUJOCO_GL={backend}: {lines[-1] if lines else 'exit ' + str(done.returncode)}")
    raise SpnError(
        f"cannot render {env_id} offscreen ({'; '.join(reasons)}): on a machine without a display install an "
        "OpenGL backend (Debian: apt-get install libosmesa6, then MUJOCO_GL=osmesa; or Mesa/GPU EGL with MUJOCO_GL=egl)"
    )


def write_video(frames: list[np.ndarray], path: Path, fps: int) -> Path:
    """Write RGB frames as an MP4 (H.264 through imageio-ffmpeg)."""
    imageio = require("imageio", "video")
    require("imageio_ffmpeg", "video")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    imageio.mimwrite(path, frames, fps=fps, codec="libx264", macro_block_size=1)
    return path


def summary(elite: Elite, episodes: Episodes) -> dict[str, float]:
    """Mean return, hidden spike rate (per neuron per simulation step) and mask density of a replay."""
    snn = elite.cfg.algo.snn
    x1, x2 = elite.masks
    return {
        "mean_return": float(episodes.returns.mean()),
        "spike_rate": spike_rate(episodes.spikes, episodes.steps, snn.hidden, snn.time_steps),
        "mask_density": mask_density(x1, x2),
    }


def log_video_to_wandb(elite: Elite, path: Path, metrics: dict[str, float]) -> None:
    """Add the video (and replay metrics) to the run's W&B run, resumed by its saved id."""
    from spn_torchrl.records import wandb_mode

    wandb = require("wandb", "wandb")
    log = elite.cfg.logger
    run = wandb.init(
        project=log.project,
        entity=log.entity,
        group=log.group,
        id=elite.state.get("wandb_id"),
        resume="allow",
        dir=str(elite.run_dir),
        mode=wandb_mode(log.mode),
        name=elite.state.get("run_name"),
    )
    try:
        run.log({"play/video": wandb.Video(str(path), format="mp4"), **{f"play/{k}": v for k, v in metrics.items()}})
    finally:
        run.finish()


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog="python -m spn_torchrl.play", description=__doc__.split("\n\n")[1])
    parser.add_argument("run_dir", type=Path, help="a GA run directory (holds checkpoint.pt)")
    parser.add_argument("--generation", type=int, default=None, help="whose elite (1-based; default: the last)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes to replay (default 10)")
    parser.add_argument("--seed", type=int, default=0, help="env seed of the replay (default 0)")
    parser.add_argument("--video", type=Path, default=None, help="write an MP4 of one episode here")
    parser.add_argument(
        "--max-steps", type=int, default=None, help="cut the recorded episode (video, pictures) after this many steps"
    )
    parser.add_argument("--pictures", type=Path, default=None, help="write spike raster and connectivity pictures here")
    return parser.parse_args(argv)


def play(args: argparse.Namespace) -> dict[str, float]:
    """Replay, print, and write what ``args`` asks for; returns the printed metrics."""
    if args.episodes < 1:
        raise SpnError(f"--episodes must be >= 1, got {args.episodes}")
    if args.max_steps is not None and args.max_steps < 1:
        raise SpnError(f"--max-steps must be >= 1, got {args.max_steps}")
    elite = load_elite(args.run_dir, args.generation)
    if args.video is not None:  # fail before the replay, not after it
        require("imageio", "video")
        require("imageio_ffmpeg", "video")
        os.environ["MUJOCO_GL"] = find_gl_backend(elite.spec.env_id)
    if args.pictures is not None:
        require("matplotlib", "pictures")
    episodes = replay(elite, args.episodes, args.seed)
    metrics = summary(elite, episodes)
    print(f"{elite.run_dir}: {elite.spec.env_id}, elite of generation {elite.generation}/{elite.generations}")
    print(
        f"returns over {args.episodes} episodes (seed {args.seed}): {[round(r, 2) for r in episodes.returns.tolist()]}"
    )
    print(f"mean return {metrics['mean_return']:.2f}  mean episode steps {float(episodes.steps.float().mean()):.1f}")
    print(f"hidden spike rate {metrics['spike_rate']:.4f} spikes per neuron per simulation step")
    print(f"mask density {metrics['mask_density']:.4f}")
    x1, x2 = elite.masks
    spec = elite.spec
    energy = inference_energy(
        spec.n_obs, spec.n_act, elite.cfg.algo.snn.hidden, metrics["spike_rate"], float(x1.sum()), float(x2.sum())
    )
    metrics.update({f"energy_{k}": v for k, v in energy.items()})
    print(
        f"inference energy per step: {energy['dense_pj']:.1f} pJ (paper, dense), "
        f"{energy['mask_aware_pj']:.1f} pJ (mask-aware)"
    )
    if args.video is not None or args.pictures is not None:
        trace = run_episode(elite, args.seed, render=args.video is not None, max_steps=args.max_steps)
        if args.video is not None:
            fps = int(gym.make(elite.spec.env_id).metadata.get("render_fps", 30))
            path = write_video(trace.frames, args.video, fps)
            print(f"video of one episode (return {trace.episode_return:.2f}, {len(trace.frames)} frames): {path}")
            if elite.cfg.logger.backend == "wandb":
                log_video_to_wandb(elite, path, metrics)
        if args.pictures is not None:
            from spn_torchrl.tools import pictures

            for path in pictures.draw_all(elite, trace.spikes, args.pictures):
                print(f"picture: {path}")
    return metrics


def main(argv: list[str] | None = None) -> None:
    try:
        play(parse_args(argv))
    except SpnError as err:
        sys.exit(f"error: {err}")


if __name__ == "__main__":
    main()
