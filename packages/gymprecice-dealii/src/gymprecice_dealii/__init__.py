"""gymprecice-dealii."""
