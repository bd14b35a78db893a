"""gymprecice's lab: train, evaluate, benchmark and judge controllers on any registered env."""
