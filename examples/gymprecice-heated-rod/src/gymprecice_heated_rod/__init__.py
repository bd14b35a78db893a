"""HeatedRod-v0: a gymprecice environment package (a heated rod, a Python solver, a card).

``import gymprecice`` registers ``heatedrod/HeatedRod-v0`` through this package's plugin
(:mod:`gymprecice_heated_rod.plugin`); the env is :class:`gymprecice_heated_rod.env.HeatedRodEnv`.
"""
