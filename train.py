"""Train an SPN (or the DPN baseline): ``python train.py algo=conn_ga env=cartpole``."""

import os
import signal
import sys


def _stopped_starting(signum: int, frame: object) -> None:
    """SIGINT or SIGTERM before a run has begun (imports, Hydra, the config's checks): one line, nothing written."""
    name = signal.Signals(signum).name
    print(f"stopped: interrupted by {name} while starting, before its run began; start it again", file=sys.stderr)
    os._exit(128 + signum)


# before the imports (seconds of torch, Hydra and TorchRL); the run installs its own handlers once it begins. Only
# as a script: a Slurm or Ray worker that imports this module keeps its launcher's handlers
if __name__ == "__main__":
    signal.signal(signal.SIGINT, _stopped_starting)
    signal.signal(signal.SIGTERM, _stopped_starting)

import hydra  # noqa: E402
from omegaconf import DictConfig  # noqa: E402

from spn_torchrl import RunInterrupted, SpnError, run  # noqa: E402
from spn_torchrl.config import register_configs  # noqa: E402

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
