"""The training wing: ``gymprecice train`` and ``gymprecice tune``.

The commands (:mod:`.train`, :mod:`.tune` with :mod:`.tune_spaces`), one training
segment (:mod:`.loop`), its envs (:mod:`.vector_env`), model (:mod:`.learner`,
:mod:`.overlap`), hyperparameters (:mod:`.hyperparams`), callbacks
(:mod:`.callbacks`, :mod:`.validation`), its logger and manifest (:mod:`.logger`, :mod:`.segments`), ``--shared-policy``
(:mod:`.shared_policy`) and the pre-run's progress lines (:mod:`.prerun_progress`).
"""
