"""``python -m spn_torchrl.play``: the command-line face of :mod:`spn_torchrl.tools.play`."""

from spn_torchrl.tools.play import main

if __name__ == "__main__":
    main()
