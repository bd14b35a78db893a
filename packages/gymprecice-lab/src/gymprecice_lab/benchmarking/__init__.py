"""The benchmark wing: ``gymprecice benchmark`` (:mod:`.command`) and its pieces.

The input checked (:mod:`.checks`), the sub-commands' lines (:mod:`.argv`), the locked
settings (:mod:`.settings`), each seed's training (:mod:`.seed_training`), where the
evaluations run (:mod:`.dispatch`, :mod:`.remote_commands` on Ray), the scores and their
intervals (:mod:`.scores`, :mod:`.stats`), the tables and figures (:mod:`.tables`,
:mod:`.plots`); and ``gymprecice time-to-floor`` (:mod:`.time_to_floor`): how far and
how soon training runs reached a card's reference, with the same intervals.
"""
