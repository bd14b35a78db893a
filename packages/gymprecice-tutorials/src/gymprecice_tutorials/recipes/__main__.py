"""``python -m gymprecice_tutorials.recipes``: see :mod:`gymprecice_tutorials.recipes.cli`."""

import sys

from gymprecice_tutorials.recipes.cli import main

sys.exit(main())
