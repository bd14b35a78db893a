"""A 1-D heated rod as a preCICE participant: the "solver" of the example.

Any program that speaks the pyprecice v3 API can be a gymprecice solver. This one reads
the controller's "Heat" at its heater vertices, advances an explicit finite-difference
heat equation, and writes "Temperature" at its sensor vertices, once per time step. It
prints one line per time window, so its log grows while it runs (gymprecice counts log
growth as progress). ``--library gymprecice.testing.fake_precice`` couples through
gymprecice's test double instead of real preCICE.
"""

from __future__ import annotations

import argparse
import importlib

import numpy as np

CELLS = 50
HEATERS = np.array([[0.25, 0.0], [0.5, 0.0], [0.75, 0.0]])
SENSORS = np.array([[0.1, 0.0], [0.4, 0.0], [0.6, 0.0], [0.9, 0.0]])


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--participant", default="Rod")
    parser.add_argument("--config", default="../precice-config.xml")
    parser.add_argument("--library", default="precice")
    args = parser.parse_args()
    precice = importlib.import_module(args.library)

    x = (np.arange(CELLS) + 0.5) / CELLS
    temperature = np.zeros(CELLS)
    heater_cells = np.rint(HEATERS[:, 0] * CELLS - 0.5).astype(int)
    sensor_cells = np.rint(SENSORS[:, 0] * CELLS - 0.5).astype(int)

    participant = precice.Participant(args.participant, args.config, 0, 1)
    heater_ids = participant.set_mesh_vertices("Rod-Mesh-heater", HEATERS)
    sensor_ids = participant.set_mesh_vertices("Rod-Mesh-sensor", SENSORS)
    participant.initialize()
    t, window = 0.0, 0
    while participant.is_coupling_ongoing():
        dt = participant.get_max_time_step_size()
        heat = participant.read_data("Rod-Mesh-heater", "Heat", heater_ids, dt)
        source = np.zeros(CELLS)
        source[heater_cells] = heat
        # explicit diffusion, stable sub-steps, ends at 0 (fixed cold ends)
        h = 1.0 / CELLS
        steps = max(1, int(np.ceil(dt / (0.4 * h * h))))
        for _ in range(steps):
            padded = np.concatenate([[0.0], temperature, [0.0]])
            laplacian = (padded[:-2] - 2 * temperature + padded[2:]) / (h * h)
            temperature = temperature + dt / steps * (laplacian + source)
        participant.write_data(
            "Rod-Mesh-sensor",
            "Temperature",
            sensor_ids,
            temperature[sensor_cells],
        )
        participant.advance(dt)
        t += dt
        if participant.is_time_window_complete():
            window += 1
            print(
                f"window {window} t={t:.6g} max T={temperature.max():.6g} at x={x[temperature.argmax()]:.3f}",
                flush=True,
            )
    participant.finalize()
    print(f"finished at t={t:.6g}", flush=True)


if __name__ == "__main__":
    main()
