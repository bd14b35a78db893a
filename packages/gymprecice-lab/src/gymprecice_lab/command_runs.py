"""The old path of :mod:`gymprecice_lab.common.command_runs`: the same module object."""

import sys

from gymprecice_lab.common import command_runs as _module

sys.modules[__name__] = _module
