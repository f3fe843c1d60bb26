"""``python -m urident.simcontroller``: run the simulated controller (same options as
``urident sim-controller``)."""

import sys

from urident.simcontroller.launch import main

if __name__ == "__main__":
    sys.exit(main())
