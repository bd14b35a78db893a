"""RotatingCylinder-v0 (see :mod:`.environment`)."""
