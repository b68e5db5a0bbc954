"""``python -m armlab.app`` = the ``armlab`` command."""

import sys

from armlab.app.commands.cli import main

if __name__ == "__main__":  # not when a worker process imports it again
    sys.exit(main())
