"""``python -m spn_torchrl.report``: the command-line face of :mod:`spn_torchrl.analysis.report`."""

from spn_torchrl.analysis.report import main

if __name__ == "__main__":
    main()
