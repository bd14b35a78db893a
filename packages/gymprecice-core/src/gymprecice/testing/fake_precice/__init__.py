"""A pure-Python stand-in for pyprecice v3 (``import precice``), faithful enough to test against.

Real preCICE is a C++ library that has to be built and installed before pyprecice can be,
so most machines that run gymprecice's tests do not have it. This package speaks the
same Python API as the ``pyprecice`` bindings (``Participant`` with the same method names,
argument order, return shapes and dtypes), follows the same call protocol, and fails the
same way, so that code written and tested against it runs unchanged against the real
library.

Use it wherever ``import precice`` would go::

    from gymprecice.testing import fake_precice as precice

    participant = precice.Participant("Controller", "precice-config.xml", 0, 1)

or select it for a gymprecice environment with ``"precice": {"library":
"gymprecice.testing.fake_precice"}`` (or ``GYMPRECICE_PRECICE_LIBRARY``). Every participant of
one coupled run must use the double: it only talks to itself (a real preCICE partner is
detected and reported, see below).

How it works:

Each participant is its own process. ``initialize()`` connects to the coupling partners
named by the ``<m2n:...>`` tags over Unix-domain sockets; the acceptor publishes the
socket address in ``<exchange-directory>/precice-run/<acceptor>-<connector>/`` (relative
to the working directory, like preCICE) and the connector waits for it without a timeout,
like preCICE. Provided meshes are sent to the participants that receive them, then the
coupling schemes exchange data exactly in the order preCICE's schemes do.

Modelled (as preCICE 3.4 does it):

* ``serial-explicit``, ``parallel-explicit``, ``serial-implicit``, ``parallel-implicit``
  and ``multi`` schemes, and several schemes per participant (preCICE's compositional
  scheme: any number of explicit ones plus at most one implicit one).
* ``max-time``, ``max-time-windows``, ``time-window-size``, ``get_max_time_step_size``
  shrinking at the end (truncated last window), subcycling, ``is_time_window_complete``.
* implicit coupling: ``max-iterations``, ``min-iterations`` and the absolute, relative,
  absolute-or-relative and residual-relative convergence measures (with ``suffices`` and
  ``strict``), checkpoint promises enforced, ``precice-<participant>-iterations.log`` and
  ``precice-<participant>-convergence.log``.
* ``exchange`` with ``initialize="true"`` (``requires_initial_data`` protocol) and
  ``substeps``; time interpolation of read data by ``waveform-degree`` (0: constant, 1
  and above: piecewise linear through the available samples).
* written data is reset to zero after every ``advance`` (preCICE does this too: write
  every time step).
* mappings ``nearest-neighbor`` (consistent and conservative, read and write), direct
  access (``api-access="true"`` + ``set_mesh_access_region``), watch points
  (``precice-<participant>-watchpoint-<name>.log``, nearest vertex).
* the protocol checks of ``ParticipantImpl`` and the assertions of the Python bindings,
  with their messages: call order, initial data, ``advance(dt)`` bounds, checkpoint
  promises, write/read after the end or after ``finalize()``, unknown meshes and data,
  invalid vertex ids, mesh modification after ``initialize()``, a leftover address file,
  a configuration file that differs between the participants.
* failure behaviour measured with preCICE 3.4.1: when a partner dies (killed, stopped,
  or exits) the surviving participant does **not** raise; it blocks in ``initialize``/
  ``advance`` forever. Whoever supervises it must kill it. (Real preCICE may first
  finish one or two more time windows with zero data before it blocks, and can even
  reach the end of the run that way if the partner died in the last windows; the double
  blocks at the first exchange that needs the dead partner. A supervisor should watch
  the solver processes themselves, not only the coupling.) The double blocks for
  :data:`PARTNER_LOSS` seconds (5) once the partner's connection has closed, time for
  a supervisor to act, then gives up with preCICE's "... This often means that the
  other participant exited with an error" :class:`PreciceError`: a solver left on the
  double when its controller was SIGKILLed ends instead of waiting for hours.
  ``GYMPRECICE_FAKE_PRECICE_PARTNER_LOSS=hang`` blocks forever, as preCICE does. A
  partner that is stopped (SIGSTOP) or hangs keeps its connection: the survivor blocks.

Not modelled:

* other mapping methods (``rbf-*``, ``nearest-projection``,
  ``linear-cell-interpolation``, ...) run as nearest-neighbor; just-in-time mappings,
  gradients, remeshing (``reset_mesh``), ``write_and_map_data`` and
  ``map_and_read_data`` raise.
* acceleration (IQN, Aitken, constant under-relaxation): implicit coupling runs plain
  fixed-point iterations; higher waveform degrees interpolate linearly.
* ``time-window-size method="first-participant"``, parallel participants
  (``solver_process_size > 1``), MPI communicators, mesh exports, profiling output.

Errors:

preCICE reports a misuse by throwing ``precice::Error`` (a ``std::runtime_error``),
which the bindings turn into a Python ``RuntimeError``; the double raises
:class:`PreciceError`, a ``RuntimeError`` subclass, with preCICE's message (and logs it
as ``ERROR:``, like preCICE). Where the bindings check arguments themselves they raise
``AssertionError``/``TypeError``, and so does the double.

Some misuses kill real pyprecice instead (measured with 3.4.1): the calls whose C++
declaration lacks ``except +`` (``finalize`` twice, ``is_coupling_ongoing``,
``is_time_window_complete``, ``get_max_time_step_size``, ``requires_*`` at the wrong
time, profiling sections) reach ``std::terminate`` and abort the process (SIGABRT, with
"terminate called after throwing an instance of 'precice::Error'" and the message on
stderr); ``advance`` before ``initialize``, and any call that needs a mesh or the
coupling after ``finalize``, end in a segmentation fault. By default the double raises
:class:`PreciceError` in these cases too, so tests can see them; with
``GYMPRECICE_FAKE_PRECICE_MISUSE=crash`` (or :data:`MISUSE` = "crash") it ends the
process exactly as preCICE does, which is what a supervisor of a participant process
should be tested against.

Where each part lives:

* :mod:`~.participant`: the ``Participant`` API and its protocol checks;
  :mod:`~.arguments` the bindings' own argument checks; :mod:`~.errors` the ways it fails.
* :mod:`~.rendezvous`: meeting the partners at ``initialize``, over :mod:`~.channel`.
* :mod:`~.schemes`: the coupling schemes, keeping time with :mod:`~.clock` and judging
  convergence with :mod:`~.convergence`.
* :mod:`~.store` and :mod:`~.waveform`: the exchanged data in time; :mod:`~.mesh`,
  :mod:`~.mapping` and :mod:`~.watchpoints`: the data in space.
* :mod:`~.config_extras`: what it reads of the XML beyond :mod:`gymprecice.precice_xml`;
  :mod:`~.version`: which preCICE it says it is.
"""

from __future__ import annotations

import os

from gymprecice.testing.fake_precice.errors import PreciceError
from gymprecice.testing.fake_precice.participant import Participant
from gymprecice.testing.fake_precice.version import (
    IS_FAKE,
    PRECICE_VERSION,
    __version__,
    get_version_information,
)

__all__ = [
    "IS_FAKE",
    "MISUSE",
    "PARTNER_LOSS",
    "PRECICE_VERSION",
    "Participant",
    "PreciceError",
    "__version__",
    "get_version_information",
]

#: What a misuse that kills real preCICE does here: "raise" (default) raises
#: :class:`PreciceError`; "crash" ends the process the way preCICE 3.4.1 does (``abort()``
#: with libstdc++'s "terminate called ..." message, or a segmentation fault). Set it here or
#: with the environment variable ``GYMPRECICE_FAKE_PRECICE_MISUSE``; :func:`.errors.fatal`
#: reads it from this module at each misuse, so setting it here takes effect at once.
MISUSE = os.environ.get("GYMPRECICE_FAKE_PRECICE_MISUSE", "raise")

#: What a participant does when a partner's connection closes (the partner was killed,
#: crashed or exited): wait this many seconds, as preCICE does, then give up with
#: preCICE's :class:`PreciceError` ("... This often means that the other participant
#: exited with an error"), so that a solver on the double never outlives its controller
#: for hours; "hang" waits forever, as preCICE 3.4.1 does. Set it here or with
#: ``GYMPRECICE_FAKE_PRECICE_PARTNER_LOSS``; read at each loss.
PARTNER_LOSS = os.environ.get("GYMPRECICE_FAKE_PRECICE_PARTNER_LOSS", "5")
