"""The command line and the installation: what ``gymprecice ...`` runs.

:mod:`~gymprecice.tools.cli` is the ``gymprecice`` command (``check``, ``doctor``,
``install``, ``clean``, ``sketch``, ``new``, and the lab's commands); its commands live
beside it (:mod:`~gymprecice.tools.doctor`, :mod:`~gymprecice.tools.install_command`,
:mod:`~gymprecice.tools.clean_command`, :mod:`~gymprecice.tools.sketch_command`), as does
what they drive: the coupling stack's build (:mod:`~gymprecice.tools.stack`,
:mod:`~gymprecice.tools.precice_install`, :mod:`~gymprecice.tools.prerequisites`), case
sketches
(:mod:`~gymprecice.tools.case_sketch`, :mod:`~gymprecice.tools.sketch_drawing`), the
installed distributions (:mod:`~gymprecice.tools.distribution`) and the one-line advice
for a missing optional dependency (:mod:`~gymprecice.tools.optional`).

This package's ``__init__`` imports nothing: a module of it is imported by name.
"""
