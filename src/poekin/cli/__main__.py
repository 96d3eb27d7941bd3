"""``python -m poekin.cli``: the ``poekin`` command."""

import sys

from poekin.cli import main

sys.exit(main())
