"""Default plugin (filled in)."""
