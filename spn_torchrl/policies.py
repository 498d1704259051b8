"""Where README's recipe loads published or exported weights: ``spn_torchrl.policies.build_spn`` (see :mod:`spn_torchrl.snn.policies`)."""

from spn_torchrl.snn.policies import PopulationSPN, build_spn

__all__ = ["PopulationSPN", "build_spn"]
