"""``python -m app`` = the ``armlab`` command."""

import sys

from app.cli import main

if __name__ == "__main__":  # not when a worker process (app.arm_process) imports it again
    sys.exit(main())
