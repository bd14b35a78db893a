"""gymprecice: Gymnasium environments from preCICE-coupled PDE simulations."""

__version__ = "0.2.0"
