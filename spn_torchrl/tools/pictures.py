"""Pictures of an evolved SPN (matplotlib, the ``pictures`` extra): the hidden layer's spike raster over an
episode, and the connectivity of both layers across generations (a grid PNG and an animated GIF)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import torch

from spn_torchrl.errors import require
from spn_torchrl.snn.policies import mask_density


def _pyplot():
    matplotlib = require("matplotlib", "pictures")
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def spike_raster(spikes: torch.Tensor, path: Path, title: str = "") -> Path:
    """PNG raster of hidden spikes [S, T', h] (env steps x simulation steps x neurons): one dot per spike."""
    plt = _pyplot()
    steps, time_steps, hidden = spikes.shape
    flat = spikes.reshape(steps * time_steps, hidden)
    t, neuron = torch.nonzero(flat, as_tuple=True)
    width = min(40.0, max(6.0, steps * time_steps / 100))
    fig, ax = plt.subplots(figsize=(width, 4), dpi=100)
    ax.scatter((t.float() / time_steps).numpy(), neuron.numpy(), s=1.0, marker="|", color="black", linewidths=0.5)
    ax.set_xlim(0, steps)
    ax.set_ylim(-0.5, hidden - 0.5)
    ax.set_xlabel(f"environment step ({time_steps} simulation steps each)")
    ax.set_ylabel("hidden neuron")
    rate = float(flat.mean()) if flat.numel() else 0.0
    ax.set_title(f"{title}  hidden spikes: {int(flat.sum())}, rate {rate:.3f} per neuron per simulation step".strip())
    return _save(fig, path)


def _mask_axes(fig, ax1, ax2, x1: np.ndarray, x2: np.ndarray):
    im1 = ax1.imshow(x1, cmap="Greys", vmin=0, vmax=1, aspect="auto", interpolation="nearest")
    im2 = ax2.imshow(x2, cmap="Greys", vmin=0, vmax=1, aspect="auto", interpolation="nearest")
    ax1.set_xlabel("observation")
    ax1.set_ylabel("hidden neuron")
    ax2.set_xlabel("hidden neuron")
    ax2.set_ylabel("action")
    ax2.yaxis.get_major_locator().set_params(integer=True)
    return im1, im2


def connectivity_grid(masks1: torch.Tensor, masks2: torch.Tensor, path: Path, max_rows: int = 8) -> Path:
    """PNG grid of the elites' masks [G, h, n] and [G, m, h] (black: synapse exists), one row per chosen
    generation (evenly spaced, first and last included), layer 1 left, layer 2 right."""
    plt = _pyplot()
    count = masks1.shape[0]
    rows = sorted({int(round(i)) for i in np.linspace(0, count - 1, min(max_rows, count))})
    fig, axes = plt.subplots(
        len(rows), 2, figsize=(10, 2.2 * len(rows)), dpi=100, squeeze=False, gridspec_kw={"width_ratios": [1, 3]}
    )
    for row, g in zip(axes, rows):
        _mask_axes(fig, row[0], row[1], masks1[g].numpy(), masks2[g].numpy())
        row[0].set_title(f"generation {g + 1}: W1 mask", fontsize=9)
        row[1].set_title(f"W2 mask (density of both layers {mask_density(masks1[g], masks2[g]):.3f})", fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def connectivity_gif(masks1: torch.Tensor, masks2: torch.Tensor, path: Path, seconds_per_frame: float = 0.25) -> Path:
    """Animated GIF of the elites' masks, one frame per generation."""
    plt = _pyplot()
    from PIL import Image

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(9, 4), dpi=80, gridspec_kw={"width_ratios": [1, 3]})
    im1, im2 = _mask_axes(fig, ax1, ax2, masks1[0].numpy(), masks2[0].numpy())
    title = fig.suptitle("")
    frames = []
    for g in range(masks1.shape[0]):
        im1.set_data(masks1[g].numpy())
        im2.set_data(masks2[g].numpy())
        density = mask_density(masks1[g], masks2[g])
        title.set_text(f"elite connectivity, generation {g + 1}/{masks1.shape[0]} (density {density:.3f})")
        fig.canvas.draw()
        frames.append(Image.fromarray(np.asarray(fig.canvas.buffer_rgba())[..., :3]))
    plt.close(fig)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    frames[0].save(path, save_all=True, append_images=frames[1:], duration=int(seconds_per_frame * 1000), loop=0)
    return path


def _save(fig, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    _pyplot().close(fig)
    return path


def draw_all(elite, spikes: torch.Tensor, out_dir: Path) -> list[Path]:
    """Spike raster of one episode of ``elite`` and its run's connectivity across generations, in ``out_dir``."""
    out_dir = Path(out_dir)
    masks1, masks2 = elite.spn.masks(elite.elites)
    name = f"{elite.spec.env_id}, elite of generation {elite.generation}:"
    return [
        spike_raster(spikes, out_dir / f"spike_raster_gen{elite.generation}.png", name),
        connectivity_grid(masks1, masks2, out_dir / "connectivity.png"),
        connectivity_gif(masks1, masks2, out_dir / "connectivity.gif"),
    ]
