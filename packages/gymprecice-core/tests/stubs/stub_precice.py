"""A minimal stand-in for ``precice`` used by core's own Adapter tests.

It needs no partner: ``initialize`` and ``advance`` return at once (reading back the time
as data), unless ``STUB_PRECICE_BLOCK_AT`` names a window at which ``advance`` blocks
forever, like real preCICE does when its partner is gone, or is ``init``: then
``initialize`` blocks, as real preCICE does until its partner connects. The faithful protocol double
lives in :mod:`gymprecice.testing.fake_precice`; this stub isolates the Adapter's own logic.
"""

from __future__ import annotations

import os
import time

import numpy as np

from gymprecice.plugin.precice_xml import load_precice_config


class Participant:
    def __init__(self, name, config_file, rank, size):
        cfg = load_precice_config(config_file)
        self.cfg = cfg
        self.name = name
        self.dt = cfg.time_window_size(name)
        self.end = cfg.end_time(name)
        self.t = 0.0
        self.windows = 0
        self.sizes = {}
        self.written = {}
        block_at = os.environ.get("STUB_PRECICE_BLOCK_AT", "-1")
        self.block_in_initialize = block_at == "init"
        self.block_at = -1 if self.block_in_initialize else int(block_at)
        log = os.environ.get("STUB_PRECICE_LOG")
        self.log = open(log, "a") if log else None  # noqa: SIM115 - lives as long as the participant

    def set_mesh_vertices(self, mesh, coords):
        coords = np.asarray(coords)
        assert coords.shape[1] == self.cfg.meshes[mesh].dimensions
        self.sizes[mesh] = len(coords)
        return np.arange(len(coords))

    def requires_initial_data(self):
        return True

    def write_data(self, mesh, data, ids, values):
        self.written[(mesh, data)] = np.array(values)
        if self.log:
            self.log.write(f"{self.t:.6f} {mesh} {data} {np.asarray(values).ravel().tolist()}\n")
            self.log.flush()

    def initialize(self):
        while self.block_in_initialize:
            time.sleep(3600)

    def is_coupling_ongoing(self):
        return self.t < self.end - 1e-9

    def get_max_time_step_size(self):
        return min(self.dt, self.end - self.t)

    def advance(self, dt):
        if self.windows == self.block_at:
            while True:
                time.sleep(3600)
        self.t += dt
        self.windows += 1

    def requires_writing_checkpoint(self):
        return False

    def requires_reading_checkpoint(self):
        return False

    def is_time_window_complete(self):
        return True

    def read_data(self, mesh, data, ids, relative_time):
        width = 1 if self.cfg.data[data].kind == "scalar" else self.cfg.meshes[mesh].dimensions
        shape = (len(ids),) if width == 1 else (len(ids), width)
        return np.full(shape, self.t)

    def finalize(self):
        pass
