"""Kind ``command``: the package's own solver program (``solver.py``, speaking the
pyprecice v3 API), which is also the stand-in that replaces any other kind's solver on the
test double.
"""

from __future__ import annotations

__all__ = ["STAND_IN"]

STAND_IN = '''\
"""{{stand_in_title}} (participant "{{participant}}").

gymprecice runs this program as a solver of kind ``command`` ({python} solver.py ...), a
new process each episode. {{stand_in_role}} It speaks the pyprecice v3 API: each time
window it reads the controller's "{{write}}" on its mesh, moves its response a step
towards GAIN * (actuation - REFERENCE) (a first-order lag of time constant TAU), and
writes the response as "{{read}}". It prints one line per time window: gymprecice counts
log growth as progress.

The preCICE bindings are the module ``--library`` names, by default the one
gymprecice exports to the solvers it launches (``GYMPRECICE_PRECICE_LIBRARY``): real
``precice``, or gymprecice's test double ``gymprecice.testing.fake_precice`` when the env
runs on it.
"""

from __future__ import annotations

import argparse
import importlib
import os

import numpy as np

MESH = "{{mesh}}"
#: what the controller writes (read here) and reads (written here)
READ, WRITE = "{{write}}", "{{read}}"
#: whether the written data is a vector (its x component carries the response)
WRITE_VECTOR = {{read_vector}}
#: the mesh's vertices (x, y): where the controller's vertices map to
VERTICES = np.array({{stand_in_vertices}})
#: the model: the response relaxes towards GAIN * (actuation - REFERENCE) in TAU
#: seconds; the actuation is the {{total_or_mean}} of what the vertices read (x of vectors)
GAIN = {{gain}}
REFERENCE = {{stand_in_reference}}
TAU = {{tau}}
TOTAL = {{total}}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participant", default="{{participant}}")
    parser.add_argument("--config", default="../precice-config.xml")
    parser.add_argument(
        "--library",
        default=os.environ.get("GYMPRECICE_PRECICE_LIBRARY", "precice"),
    )
    args = parser.parse_args()
    precice = importlib.import_module(args.library)

    participant = precice.Participant(args.participant, args.config, 0, 1)
    ids = participant.set_mesh_vertices(MESH, VERTICES)
    participant.initialize()
    response, t, window = 0.0, 0.0, 0
    while participant.is_coupling_ongoing():
        dt = participant.get_max_time_step_size()
        read = np.asarray(participant.read_data(MESH, READ, ids, dt), dtype=float)
        actuation = read[:, 0] if read.ndim > 1 else read
        actuation = actuation.sum() if TOTAL else actuation.mean()
        target = GAIN * (actuation - REFERENCE)
        response += (target - response) * (1.0 - np.exp(-dt / TAU))
        values = np.full(len(ids), response)
        if WRITE_VECTOR:
            values = np.column_stack([values, np.zeros(len(ids))])
        participant.write_data(MESH, WRITE, ids, values)
        participant.advance(dt)
        t += dt
        if participant.is_time_window_complete():
            window += 1
            print(f"window {window} t={t:.6g} response={response:.6g}", flush=True)
    participant.finalize()
    print(f"finished at t={t:.6g}", flush=True)


if __name__ == "__main__":
    main()
'''
