"""The policies wing: a trained policy on disk, shipped, found and run.

What a policy is (:mod:`.policy`), the policies a package ships and ``gymprecice
policies`` (:mod:`.shipped`), ``gymprecice ship-policy`` (:mod:`.ship`, with the model
slimmed by :mod:`.slim_model`) and the env fitted to a policy (:mod:`.fitted_env`).
"""
