"""``python -m urident.simcontroller``: run the simulated controller (same options as
``urident sim-controller``; an entry point, like the console script)."""

import sys

from urident.cli.cmd_sim_controller import main

if __name__ == "__main__":
    sys.exit(main())
