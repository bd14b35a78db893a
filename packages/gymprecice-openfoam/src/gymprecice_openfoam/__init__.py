"""gymprecice-openfoam."""
