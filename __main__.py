"""``python -m impactqp``: the command line."""

import sys

from impactqp.scenarios.cli import main

sys.exit(main())
