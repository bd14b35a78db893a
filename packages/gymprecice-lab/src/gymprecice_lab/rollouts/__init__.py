"""The rollouts wing: fixed controllers run on an env, and what is read from the runs.

``gymprecice evaluate | baseline | open-loop | feedback`` (:mod:`.evaluate`, with the
controllers of :mod:`.controllers` and :mod:`.feedback`, the loop of :mod:`.rollout`
and the files of :mod:`.records`), ``sweep``, ``compare`` and ``plot``; ``--video`` (:mod:`.video`).
"""
