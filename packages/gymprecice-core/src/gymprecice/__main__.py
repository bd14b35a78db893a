"""``python -m gymprecice``: the same command line as ``gymprecice``."""

import sys

from gymprecice.tools.cli import main

if __name__ == "__main__":
    sys.exit(main())
