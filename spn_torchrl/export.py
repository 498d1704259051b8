"""``python -m spn_torchrl.export``: the command-line face of :mod:`spn_torchrl.tools.export`."""

from spn_torchrl.tools.export import main

if __name__ == "__main__":
    main()
