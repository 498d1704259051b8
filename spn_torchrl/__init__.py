"""Spiking policy networks whose synaptic connections are evolved by a genetic algorithm, on TorchRL."""

import os

# Importing MuJoCo (TorchRL's envs do, so every command does) fails under a MUJOCO_GL it does not know, though only
# rendering reads the value: it is set aside here, and rendering (play --video) names it in one sentence
_MUJOCO_GL_KNOWN = {"", "enable", "enabled", "on", "true", "1", "disable", "disabled", "off", "false", "0"}
_MUJOCO_GL_KNOWN |= {"glfw", "glx", "egl", "osmesa", "wgl", "cgl"}
if os.environ.get("MUJOCO_GL", "").lower().strip() not in _MUJOCO_GL_KNOWN:
    os.environ["SPN_TORCHRL_UNKNOWN_MUJOCO_GL"] = os.environ.pop("MUJOCO_GL")

from spn_torchrl.errors import (  # noqa: E402
    CheckpointError,
    ConfigError,
    EvaluatorError,
    RunFileError,
    RunInterrupted,
    SpnError,
)
from spn_torchrl.run import run  # noqa: E402

__all__ = ["run", "SpnError", "ConfigError", "CheckpointError", "EvaluatorError", "RunFileError", "RunInterrupted"]
