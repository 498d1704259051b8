"""Spiking policy networks whose synaptic connections are evolved by a genetic algorithm, on TorchRL."""

from spn_torchrl.errors import CheckpointError, ConfigError, EvaluatorError, RunFileError, SpnError
from spn_torchrl.run import run

__all__ = ["run", "SpnError", "ConfigError", "CheckpointError", "EvaluatorError", "RunFileError"]
