"""``python -m spn_torchrl.report``: the command-line face of :mod:`spn_torchrl.analysis.report` and, with
``--reproduction``, of :mod:`spn_torchrl.analysis.reproduction`."""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from spn_torchrl.analysis.report import build_report, log_to_wandb
from spn_torchrl.analysis.reproduction import build_reproduction
from spn_torchrl.errors import SpnError


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="python -m spn_torchrl.report",
        description="One report over run / multirun directories: curves over seeds, data efficiency, energy.",
    )
    parser.add_argument("paths", nargs="+", help="run or multirun directories (searched recursively)")
    parser.add_argument("--ppo-level", type=float, default=None, help="PPO level R (default: from dpn_ppo runs found)")
    parser.add_argument("--out", type=Path, default=None, help="output directory (default: ./report)")
    parser.add_argument(
        "--reproduction",
        action="store_true",
        help="write README.md: the runs (finished ones only) against the paper's published figures, claim by claim",
    )
    parser.add_argument(
        "--v2",
        nargs="+",
        default=[],
        metavar="PATH",
        help="with --reproduction: runs on MuJoCo 2.1's dynamics (env.backend=gym_v2 or mujoco_batch_mj210), "
        "judged beside the v5 runs",
    )
    parser.add_argument(
        "--wandb",
        action="store_true",
        help="also log figures and tables to W&B (automatic when every run used logger=wandb)",
    )
    parser.add_argument(
        "--wandb-project", default=None, help="W&B project (default: the runs' logger.project, else spn_torchrl)"
    )
    return parser.parse_args(argv)


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
    if args.ppo_level is not None and not math.isfinite(args.ppo_level):
        sys.exit(f"error: --ppo-level must be a finite return, got {args.ppo_level}")
    np.seterr(all="ignore")
    out = args.out or Path("report")
    if args.v2 and not args.reproduction:
        sys.exit("error: --v2 goes with --reproduction (the claims table on v2 beside v5)")
    try:
        if args.reproduction:
            result = build_reproduction(args.paths, out, args.ppo_level, v2=args.v2)
        else:
            result = build_report(args.paths, out, args.ppo_level)
            if args.wandb or result["wandb_projects"]:
                log_to_wandb(result, args.wandb_project or (result["wandb_projects"] or ["spn_torchrl"])[0])
    except SpnError as err:
        sys.exit(f"error: {err}")
    print(f"wrote {result['markdown']} ({len(result['tasks'])} task(s))")
    for run in result["stopped"]:
        print(
            f"stopped before its budget (listed apart in the report): {run['env']} {run['algo']} seed {run['seed']}: {run['progress']}"
        )


if __name__ == "__main__":
    main()
