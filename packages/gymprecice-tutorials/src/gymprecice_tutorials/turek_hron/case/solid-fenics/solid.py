"""FSI3's bar as preCICE participant ``Solid``, in legacy FEniCS through fenicsprecice.

The bar of ``bar.py`` (St. Venant-Kirchhoff, Newmark) reads the fluid's ``Stress`` on
its wetted faces (the long sides and the tip) as a traction per reference area, and
writes its ``Displacement`` there, on preCICE's ``Solid-Mesh``: the same data, meshes
and watch point (``Flap-Tip``, point A) as the deal.II program, so one
``precice-config.xml`` serves either solid.

``solid.json`` beside this script sets the run::

    {"cells": [36, 4], "degree": 2,
     "load": "rbf",            # the fluid's stress between the coupling vertices (below)
     "start_state": null,      # an .npz of Bar.save to start from (null: at rest)
     "save_dir": null,         # where to save states (null: none)
     "save_times": []}         # simulated times (s) to save the state at, and at the end

``load``: ``"rbf"``, fenicsprecice's coupling expression (a radial-basis interpolant of
the vertices' data, evaluated in Python at every quadrature point: the validated runs'),
or ``"vertex"``, :class:`bar.VertexTraction` (linear between the vertices, assembled in
compiled code: half the CPU of a coupled run on the coarse mesh, not yet validated over
the benchmark's 8 s).

A state saved at time t is ``<save_dir>/state-<t>.npz`` (t to the microsecond); the
last one, at the end of the coupling, is ``<save_dir>/state-end.npz``.

When the env renders (``GYMPRECICE_FIELDS`` names ``displacement``), the displacement at
the mesh vertices goes to ``gymprecice-fields/displacement.npz`` at the start and once
per action (``GYMPRECICE_FIELD_INTERVAL``), on the coupling's clock (from 0 at the start,
whatever time a saved state began at), as the gymprecice-fenics plugin reads it.
"""

import json
import os

import numpy as np
from bar import FSI3, Bar, VertexTraction, wetted
from dolfin import AutoSubDomain
from fenicsprecice import Adapter

with open("solid.json") as handle:
    SETTINGS = json.load(handle)

LOAD = SETTINGS.get("load", "rbf")
if LOAD not in ("rbf", "vertex"):
    raise SystemExit(f"solid.json: load must be 'rbf' or 'vertex', got {LOAD!r}")
FIELDS = [name for name in os.environ.get("GYMPRECICE_FIELDS", "").split(",") if name]
FIELD_INTERVAL = float(os.environ.get("GYMPRECICE_FIELD_INTERVAL") or 0.0)
if set(FIELDS) - {"displacement"}:
    raise SystemExit(f"solid.py writes the field displacement only; gymprecice asked for {FIELDS}")

precice = Adapter(adapter_config_filename="precice-adapter-config.json")
traction = None


def start_displacement(function_space):
    """The start state's displacement, the coupling's initial data (a case whose
    preCICE configuration initializes ``Displacement``: a restart, whose fluid mesh is
    already deformed); without a start state the function space, and no initial data."""
    if not SETTINGS.get("start_state"):
        return function_space
    from dolfin import Function

    displacement = Function(function_space)
    with np.load(SETTINGS["start_state"]) as saved:
        displacement.vector().set_local(saved["u"])  # Bar.load checks the state's size
    displacement.vector().apply("insert")
    return displacement


def coupling_traction(function_space):
    """The fluid's stress on the wetted faces, made once preCICE knows the coupling
    vertices of the bar's function space (``load`` above)."""
    global traction
    precice.initialize(
        AutoSubDomain(wetted),
        read_function_space=function_space,
        write_object=start_displacement(function_space),
    )
    if LOAD == "vertex":
        traction = VertexTraction(function_space.mesh())
        return traction.function
    traction = precice.create_coupling_expression()
    return traction


def update_traction(data):
    if LOAD == "vertex":
        traction.update(data)
    else:
        precice.update_coupling_expression(traction, data)


bar = Bar(FSI3, tuple(SETTINGS["cells"]), SETTINGS["degree"], traction=coupling_traction)
if SETTINGS.get("start_state"):
    bar.load(SETTINGS["start_state"])
save_dir = SETTINGS.get("save_dir")
pending = sorted(float(t) for t in SETTINGS.get("save_times") or [])


def save(name):
    os.makedirs(save_dir, exist_ok=True)
    bar.save(os.path.join(save_dir, name))


began = bar.time  # the coupling's clock starts at 0 here


def write_displacement():
    """``gymprecice-fields/displacement.npz`` for env.render(), replaced whole."""
    mesh = bar.mesh
    values = bar.u_n.compute_vertex_values(mesh).reshape(2, -1).T
    os.makedirs("gymprecice-fields", exist_ok=True)
    with open("gymprecice-fields/.displacement.npz", "wb") as out:
        np.savez(
            out,
            time=np.array(bar.time - began),
            points=mesh.coordinates(),
            values=np.linalg.norm(values, axis=1),
            displacement=values,
            triangles=mesh.cells().astype(np.int64),
            label=np.array("|d| [m]"),
        )
    os.replace("gymprecice-fields/.displacement.npz", "gymprecice-fields/displacement.npz")


if FIELDS:
    write_displacement()

while precice.is_coupling_ongoing():
    if precice.requires_writing_checkpoint():
        precice.store_checkpoint(bar.state(), bar.time, 0)
    step = precice.get_max_time_step_size()
    update_traction(precice.read_data(step))
    bar.step(step)
    precice.write_data(bar.u)
    precice.advance(step)
    if precice.requires_reading_checkpoint():
        functions, time, _ = precice.retrieve_checkpoint()
        bar.restore(functions, time)
    else:
        bar.advance(step)
        while save_dir and pending and bar.time >= pending[0] - step / 2:
            save(f"state-{pending.pop(0):.6f}.npz")
        if FIELDS and FIELD_INTERVAL > 0:
            frames = (bar.time - began) / FIELD_INTERVAL
            if abs(frames - round(frames)) < 1e-6 * max(1.0, frames):
                write_displacement()

if save_dir:
    save("state-end.npz")
precice.finalize()
