"""gymprecice-tutorials."""
