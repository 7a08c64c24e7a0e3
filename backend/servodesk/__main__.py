"""``python -m servodesk`` runs the command-line interface."""

import sys

from servodesk.cli import main

sys.exit(main())
