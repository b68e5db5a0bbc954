"""``python -m app`` = the ``armlab`` command."""

import sys

from app.cli import main

sys.exit(main())
