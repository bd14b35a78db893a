"""The robustness wrappers of ``--wrap`` and the hyperparameter file's ``robustness`` key.

:mod:`gymprecice.robustness` does the work; this module only merges the two sources and
turns a bad option into a command-line error. It imports gymprecice lazily: importing
gymprecice loads every plugin, which the command modules must not do at import time.
"""

from __future__ import annotations

import argparse
from typing import Any

__all__ = ["WrapError", "parse_wrap_argument", "wrap_spec"]


class WrapError(ValueError):
    """A robustness wrapper name, key or value is wrong (the message says the fix)."""


def parse_wrap_argument(text: str) -> dict[str, Any]:
    """One ``--wrap NAME:KEY=VALUE,...`` for argparse (``type=``)."""
    from gymprecice.learners.robustness import parse_wrap_option
    from gymprecice.plugin.errors import ConfigError

    try:
        return parse_wrap_option(text)
    except ConfigError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def wrap_spec(*parts: Any) -> dict[str, Any]:
    """Robustness specs (dicts, or lists of ``--wrap`` dicts) merged, later ones winning
    per wrapper, and checked; a bad one raises :class:`WrapError`."""
    from gymprecice.learners.robustness import checked_spec
    from gymprecice.plugin.errors import ConfigError

    merged: dict[str, Any] = {}
    for part in parts:
        for entry in part if isinstance(part, list) else [part or {}]:
            merged.update(entry)
    try:
        return checked_spec(merged)
    except ConfigError as exc:
        raise WrapError(str(exc)) from None
