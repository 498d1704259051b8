"""Train an SPN (or the DPN baseline): ``python train.py algo=conn_ga env=cartpole``."""

import sys

import hydra
from omegaconf import DictConfig

from spn_torchrl import SpnError, run
from spn_torchrl.config import register_configs

register_configs()


@hydra.main(version_base=None, config_path="conf", config_name="config")
def main(cfg: DictConfig) -> None:
    try:
        run(cfg)
    except SpnError as err:
        sys.exit(f"error: {err}")


if __name__ == "__main__":
    main()
