"""Hook implementations (filled in)."""
