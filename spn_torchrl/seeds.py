"""Every seed a run derives from its own: the env seeds of its rollouts, so that a resumed run replays them."""

from __future__ import annotations

import numpy as np


def episode_seed(run_seed: int, generation: int, phase: int) -> int:
    """Env seed of one rollout, derived from the run seed so that a resumed run replays it exactly."""
    return int(np.random.SeedSequence([run_seed, generation, phase]).generate_state(1)[0] >> 1)
