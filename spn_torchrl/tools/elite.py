"""Load a finished (or running) GA run's elite: its config, task, fixed weights and SPN, from checkpoint.pt."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import torch

from spn_torchrl import checkpoint
from spn_torchrl.config import RunConfig, from_saved
from spn_torchrl.envs import TaskSpec, task_spec
from spn_torchrl.errors import CheckpointError, SpnError
from spn_torchrl.snn.observations import Norm
from spn_torchrl.snn.policies import PopulationSPN, spn_from_config


@dataclass
class Elite:
    """One generation's elite of a run, with the SPN (population of one) already set to it and to the
    observation normalisation its re-evaluation used (``obs_norm``, [1, n] each; None: raw observations)."""

    run_dir: Path
    cfg: RunConfig
    spec: TaskSpec
    spn: PopulationSPN
    genome: torch.Tensor
    generation: int
    generations: int
    elites: torch.Tensor
    state: dict
    obs_norm: Norm | None = None

    @property
    def masks(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Connection masks of the elite, [h, n] and [m, h]."""
        x1, x2 = self.spn.masks(self.genome[None])
        return x1[0], x2[0]

    @property
    def weights(self) -> tuple[torch.Tensor, torch.Tensor]:
        """Effective (masked) weights of the elite, [h, n] and [m, h]."""
        w1, w2 = self.spn.effective_weights(self.genome[None])
        return w1[0], w2[0]


def load_elite(run_dir: str | Path, generation: int | None = None) -> Elite:
    """The elite of ``generation`` (1-based; default the last saved) of the GA run in ``run_dir``."""
    run_dir = Path(run_dir)
    if not run_dir.exists():
        raise SpnError(f"run directory {run_dir} does not exist")
    state = checkpoint.load(run_dir)
    if state["meta"].get("format") not in checkpoint.GA_FORMATS_READABLE:
        raise CheckpointError(
            f"{run_dir} holds a {state['meta'].get('format')!r} checkpoint, not a GA run ({checkpoint.GA_FORMAT})"
        )
    cfg = from_saved(state["config"])
    elites = state["elites"]
    count = elites.shape[0]
    if count == 0:
        raise SpnError(
            f"{run_dir} holds no finished generation yet (the first elite's re-evaluation had not ended when it "
            "stopped): resume the run for at least one generation first"
        )
    generation = count if generation is None else generation
    if not 1 <= generation <= count:
        raise SpnError(f"--generation must be in [1, {count}] for {run_dir}, got {generation}")
    spec = task_spec(state["meta"]["env_id"])
    spn = spn_from_config(cfg.algo.snn, cfg.algo.genome, spec, state["w1"], state["w2"])
    genome = elites[generation - 1]
    spn.set_genomes(genome[None])
    norms = state.get("elite_norms")  # [2, G, n] where the run normalised observations
    norm = None if norms is None else (norms[0, generation - 1][None], norms[1, generation - 1][None])
    spn.set_observation_norm(norm)
    return Elite(run_dir, cfg, spec, spn, genome, generation, count, elites, state, norm)
