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

    class DryRunAdapter:
        def __init__(self, adapter_config_filename="precice-adapter-config.json", **_):
            self._config = Config(adapter_config_filename)

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
            out = {
                "participant": self._config.get_participant_name(),
                "mesh": self._config.get_coupling_mesh_name(),
                "coordinates": [list(map(float, c)) for c in coords],
            }
            sys.stdout.write("GYMPRECICE-DRY-RUN " + json.dumps(out) + "\n")
            sys.stdout.flush()
            os._exit(0)

    fenicsprecice.Adapter = DryRunAdapter
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
