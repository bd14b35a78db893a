"""Run a FEniCS participant script up to its coupling, report its interface, stop.

Run *by the FEniCS solver environment's interpreter* (not imported by the plugin, and it
imports nothing of gymprecice, which that interpreter does not have)::

    python dry_run.py SCRIPT

in the script's run directory. ``fenicsprecice.Adapter`` is replaced by a stand-in that
reads the adapter file like the real one, and whose ``initialize(coupling_subdomain,
read_function_space, write_object)`` records the interface vertices exactly as fenicsprecice
would give them to preCICE, prints them as one JSON line and ends the process. So one short
run (no preCICE, no partner) shows whether the script imports, builds its mesh and reaches
the coupling, and where its coupling vertices are.

fenicsprecice 2.x couples one mesh; a script with a second mesh (a heater on another
boundary) sets its vertices through the adapter's participant (``adapter._participant.
set_mesh_vertices(mesh, coords)``) before ``initialize``. The stand-in records those too,
so every mesh the script provides has its vertices in the answer.

Exit status: 0 with a ``GYMPRECICE-DRY-RUN {json}`` line; 3 when the script raised (its
traceback on stderr); 4 when it ended without initializing the adapter.
"""

import json
import os
import runpy
import sys
import traceback


def main(script):
    import fenicsprecice
    from fenicsprecice.adapter_core import get_fenics_vertices
    from fenicsprecice.config import Config

    meshes = {}

    class RecordingParticipant:
        """What a script may ask of preCICE before the coupling starts."""

        def set_mesh_vertices(self, mesh, coordinates):
            rows = [list(map(float, c)) for c in coordinates]
            meshes.setdefault(mesh, []).extend(rows)
            start = len(meshes[mesh]) - len(rows)
            return list(range(start, len(meshes[mesh])))

        def set_mesh_vertex(self, mesh, coordinate):
            return self.set_mesh_vertices(mesh, [coordinate])[0]

        def get_mesh_dimensions(self, mesh):
            return 2 if not meshes.get(mesh) else len(meshes[mesh][0])

        def requires_mesh_connectivity_for(self, mesh):
            return False

    class DryRunAdapter:
        def __init__(self, adapter_config_filename="precice-adapter-config.json", **_):
            self._config = Config(adapter_config_filename)
            self._participant = RecordingParticipant()

        def initialize(self, coupling_subdomain, read_function_space=None, write_object=None, **_):
            space = read_function_space
            if space is None and write_object is not None:
                space = getattr(write_object, "function_space", lambda: write_object)()
            if space is None:
                raise ValueError(
                    "Adapter.initialize got neither read_function_space nor write_object"
                )
            dims = space.tabulate_dof_coordinates().shape[1]
            _, _, coords = get_fenics_vertices(space, coupling_subdomain, dims)
            mesh = self._config.get_coupling_mesh_name()
            meshes[mesh] = [list(map(float, c)) for c in coords]
            out = {
                "participant": self._config.get_participant_name(),
                "mesh": mesh,
                "coordinates": meshes[mesh],
                "meshes": meshes,
            }
            sys.stdout.write("GYMPRECICE-DRY-RUN " + json.dumps(out) + "\n")
            sys.stdout.flush()
            os._exit(0)

    fenicsprecice.Adapter = DryRunAdapter
    # as ``python SCRIPT`` does: the script's own modules beside it import
    sys.path.insert(0, os.path.dirname(os.path.abspath(script)))
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit:
        pass
    except BaseException:
        traceback.print_exc()
        sys.stderr.flush()
        os._exit(3)
    sys.stderr.write(f"{script} ended without calling fenicsprecice.Adapter.initialize\n")
    os._exit(4)


if __name__ == "__main__":
    main(sys.argv[1])
