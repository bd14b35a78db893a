"""Old path of :mod:`gymprecice.env.owner_watchdog` (an alias: the same module object).

Also the watchdog's command: ``python -m gymprecice.owner_watchdog ...`` (the name
that ``gymprecice clean`` and the chaos tests look for in a process's arguments).
"""

import sys

from gymprecice.env import owner_watchdog as _module

if __name__ == "__main__":
    sys.exit(_module.main())
sys.modules[__name__] = _module
