"""Quickstart-v0 (see :mod:`.environment`)."""
