"""Train an SPN (or the DPN baseline): ``python train.py algo=conn_ga env=cartpole``."""

import sys

import hydra
from omegaconf import DictConfig

from spn_torchrl import RunInterrupted, SpnError, run
from spn_torchrl.config import register_configs

register_configs()


@hydra.main(version_base=None, config_path="conf", config_name="config")
def main(cfg: DictConfig) -> None:
    try:
        run(cfg)
    except RunInterrupted as err:
        print(f"stopped: {err}", file=sys.stderr)
        sys.exit(128 + err.signum)
    except SpnError as err:
        sys.exit(f"error: {err}")


if __name__ == "__main__":
    main()
