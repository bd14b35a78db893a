"""The rod: a 1-D heat equation as a preCICE participant (participant "Rod").

Any program that speaks the pyprecice v3 API can be a gymprecice solver; gymprecice runs
this one as a solver of kind ``command`` (``{python} solver.py ...``), a new process each
episode. Each time window it reads the controller's "Heat" (K/s) at its three heaters and
at the load, advances ``dT/dt = d²T/dx² + heat`` on ``CELLS`` cells with both ends held
at 0 K (explicit finite differences, stable sub-steps), and writes "Temperature" (K) at
its four sensors. It prints one line per time window: gymprecice counts log growth as
progress.

The preCICE bindings are the module ``--library`` names, by default the one gymprecice
exports to the solvers it launches (``GYMPRECICE_PRECICE_LIBRARY``): real ``precice``, or
gymprecice's test double ``gymprecice.testing.fake_precice`` when the env runs on it.
"""

from __future__ import annotations

import argparse
import importlib
import os

import numpy as np

CELLS = 50
HEATERS = np.array([[0.25, 0.0], [0.5, 0.0], [0.75, 0.0]])
LOAD = np.array([[0.6, 0.0]])
SENSORS = np.array([[0.1, 0.0], [0.4, 0.0], [0.6, 0.0], [0.9, 0.0]])


def cells(points: np.ndarray) -> np.ndarray:
    """The cell holding each point."""
    return np.rint(points[:, 0] * CELLS - 0.5).astype(int)


def advance(
    temperature: np.ndarray, source: np.ndarray, dt: float
) -> np.ndarray:
    """``temperature`` after ``dt`` seconds of diffusion and ``source`` (K/s per cell)."""
    h = 1.0 / CELLS
    steps = max(1, int(np.ceil(dt / (0.4 * h * h))))
    for _ in range(steps):
        padded = np.concatenate([[0.0], temperature, [0.0]])
        laplacian = (padded[:-2] - 2 * temperature + padded[2:]) / (h * h)
        temperature = temperature + dt / steps * (laplacian + source)
    return temperature


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--participant", default="Rod")
    parser.add_argument("--config", default="../precice-config.xml")
    parser.add_argument(
        "--library",
        default=os.environ.get("GYMPRECICE_PRECICE_LIBRARY", "precice"),
    )
    args = parser.parse_args()
    precice = importlib.import_module(args.library)

    temperature = np.zeros(CELLS)
    participant = precice.Participant(args.participant, args.config, 0, 1)
    heater_ids = participant.set_mesh_vertices("Rod-Mesh-heater", HEATERS)
    load_ids = participant.set_mesh_vertices("Rod-Mesh-load", LOAD)
    sensor_ids = participant.set_mesh_vertices("Rod-Mesh-sensor", SENSORS)
    participant.initialize()
    t, window = 0.0, 0
    while participant.is_coupling_ongoing():
        dt = participant.get_max_time_step_size()
        source = np.zeros(CELLS)
        source[cells(HEATERS)] += participant.read_data(
            "Rod-Mesh-heater", "Heat", heater_ids, dt
        )
        source[cells(LOAD)] += participant.read_data(
            "Rod-Mesh-load", "Heat", load_ids, dt
        )
        temperature = advance(temperature, source, dt)
        participant.write_data(
            "Rod-Mesh-sensor",
            "Temperature",
            sensor_ids,
            temperature[cells(SENSORS)],
        )
        participant.advance(dt)
        t += dt
        if participant.is_time_window_complete():
            window += 1
            print(
                f"window {window} t={t:.6g} mean T={temperature.mean():.6g}",
                flush=True,
            )
    participant.finalize()
    print(f"finished at t={t:.6g}", flush=True)


if __name__ == "__main__":
    main()
