"""``python -m poekin``: the ``poekin`` command."""

import sys

from poekin.cli import main

sys.exit(main())
