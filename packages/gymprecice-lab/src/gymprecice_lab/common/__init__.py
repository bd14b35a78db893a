"""What every wing of the lab shares.

ENV resolved to a registered id and its lab card (:mod:`.registered_env`), the env's
constructor arguments from a command's options (:mod:`.constructor_kwargs`), the env
wrapped as training wraps it and a model loaded into it (:mod:`.wrapped_env`), the
held-out and validation starts (:mod:`.starts`), ``manifest.json``
(:mod:`.manifest`), the solvers an env needs (:mod:`.requirements`), ``--wrap``
(:mod:`.wrapping`), which model of a training run a command takes (:mod:`.kept_model`)
and lab commands run from lab commands (:mod:`.command_runs`).
"""
