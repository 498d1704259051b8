"""Reading finished runs: the energy model (energy), runs on disk (runs), the report and its figures."""
