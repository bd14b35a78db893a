"""Old path of :mod:`gymprecice.plugin.precice_xml` (an alias: the same module object)."""

import sys

from gymprecice.plugin import precice_xml as _module

sys.modules[__name__] = _module
