"""Old path of :mod:`gymprecice.plugin.fields` (an alias: the same module object)."""

import sys

from gymprecice.plugin import fields as _module

sys.modules[__name__] = _module
