"""Copy finished runs into committed evidence: ``reproduction/runs/{env}__{algo}__{seed}/``.

``python -m spn_torchrl.analysis.collect RUN_DIR... --into reproduction/runs [--commit HASH] [--replace]``
copies each run's ``progress.csv`` (byte for byte), its resolved config as ``config.yaml`` and a ``COMMIT`` file
(the commit of the code that made the run: ``--commit``, else the run's own COMMIT file). It refuses a run that
did not reach its budget (GA: as many rows as ``algo.generations``; PPO: the last ``total_env_steps`` at
``algo.total_env_steps``), a file over 1 MB, and an existing different file unless ``--replace`` is given.
Every run is tried; the exit status is non-zero if any was refused.
"""

from __future__ import annotations

import argparse
import re
import sys
from collections.abc import Sequence
from pathlib import Path

from omegaconf import OmegaConf
from omegaconf.errors import OmegaConfBaseException

from spn_torchrl.analysis.runs import RunRecord, config_path
from spn_torchrl.errors import SpnError
from spn_torchrl.records import read_progress, write_atomic

MAX_BYTES = 1_000_000
COMMIT_RE = re.compile(r"^[0-9a-f]{7,40}$")


class CollectError(SpnError):
    """A run cannot be collected: unfinished, too large, of unknown commit, or in conflict with a collected copy."""


def evidence_name(run: RunRecord) -> str:
    """``{env}__{algo}__{seed}``: the directory a run's evidence lives in."""
    return f"{run.env}__{run.algo}__{run.seed}"


def read_run(run_dir: str | Path) -> RunRecord:
    """The run in ``run_dir`` (progress.csv and its config), or :class:`CollectError` saying what is missing."""
    run_dir = Path(run_dir)
    if not run_dir.is_dir():
        raise CollectError(f"{run_dir} is not a run directory (it does not exist or is a file)")
    config = config_path(run_dir)
    rows = read_progress(run_dir / "progress.csv")
    if config is None or not rows:
        raise CollectError(f"{run_dir} holds no progress.csv rows or no .hydra/config.yaml / config.yaml")
    return RunRecord(run_dir.resolve(), OmegaConf.load(config), rows)


def resolved_config(run: RunRecord) -> str:
    """The run's config as YAML with every interpolation resolved."""
    try:
        return OmegaConf.to_yaml(run.config, resolve=True)
    except OmegaConfBaseException as err:
        raise CollectError(f"{run.path}: its config does not resolve outside Hydra ({err})") from None


def run_commit(run: RunRecord, commit: str | None) -> str:
    """``commit`` if given, else the run's own COMMIT file; a full or abbreviated lowercase hex hash."""
    if commit is None and (run.path / "COMMIT").is_file():
        commit = (run.path / "COMMIT").read_text().strip()
    if commit is None:
        raise CollectError(f"{run.path} records no commit: pass --commit HASH (the commit that made the run)")
    if not COMMIT_RE.match(commit):
        raise CollectError(f"--commit must be a hex commit hash of 7 to 40 characters, got {commit!r}")
    return commit


def collect_run(run_dir: str | Path, into: str | Path, commit: str | None = None, replace: bool = False) -> str:
    """Copy one finished run into ``into/{env}__{algo}__{seed}/``; a line saying what was done."""
    run = read_run(run_dir)
    if run.budget is None:
        raise CollectError(f"{run.path}: its config states no budget (algo.generations / algo.total_env_steps)")
    if not run.finished:
        raise CollectError(f"{run.path} did not reach its budget: {run.progress_text}")
    files = {
        "progress.csv": (run.path / "progress.csv").read_bytes(),
        "config.yaml": resolved_config(run).encode(),
        "COMMIT": (run_commit(run, commit) + "\n").encode(),
    }
    target = Path(into) / evidence_name(run)
    if target.resolve() == run.path:
        return f"{target}: already in place"
    for name, data in files.items():
        if len(data) > MAX_BYTES:
            raise CollectError(f"{run.path}: {name} is {len(data)} bytes, over the {MAX_BYTES}-byte limit of evidence")
    changed = [
        name for name, data in files.items() if (target / name).exists() and (target / name).read_bytes() != data
    ]
    if all((target / name).is_file() and (target / name).read_bytes() == data for name, data in files.items()):
        return f"{target}: already collected, identical"
    if changed and not replace:
        raise CollectError(
            f"{target} already holds a different {', '.join(changed)}: pass --replace to overwrite it (from {run.path})"
        )
    for name, data in files.items():
        if not (target / name).exists() or name in changed:
            write_atomic(target / name, data)
    if changed:
        return f"{target}: replaced {', '.join(changed)} from {run.path}"
    return f"{target}: collected from {run.path} ({run.progress_text})"


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m spn_torchrl.analysis.collect", description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="finished run directories")
    parser.add_argument("--into", type=Path, default=Path("reproduction/runs"), help="default: reproduction/runs")
    parser.add_argument("--commit", default=None, help="the commit that made the runs (default: each run's COMMIT)")
    parser.add_argument("--replace", action="store_true", help="overwrite collected files that differ")
    args = parser.parse_args(argv)
    refused = 0
    for run_dir in args.runs:
        try:
            print(collect_run(run_dir, args.into, args.commit, args.replace))
        except SpnError as err:
            refused += 1
            print(f"error: {err}", file=sys.stderr)
    if refused:
        sys.exit(f"error: {refused} of {len(args.runs)} run(s) refused")


if __name__ == "__main__":
    main()
