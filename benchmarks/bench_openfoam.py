"""Benchmark of the OpenFOAM plugin's two per-environment costs, each beside a baseline.

1. Interface geometry: face centres, normals and areas of three patches (cylinder, jet1,
   jet2) of a ~16k-cell cylinder-in-channel mesh made by blockMesh, in ASCII and binary,
   cold (files parsed) and warm (cached), against a naive baseline: foamlib's full parse
   of points and faces plus a pure-Python loop per face. Target: <= 0.1 s.
2. Observation reads: 151 pressure probes, 50 solver steps per environment step. The
   incremental reader parses only the new rows; the naive baseline loads the whole file
   with ``numpy.loadtxt`` every step (its cost grows with the episode).

Run: ``python benchmarks/bench_openfoam.py`` (needs OpenFOAM for part 1). Prints figures;
it is not a test.
"""

from __future__ import annotations

import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from foamlib import FoamFile

from gymprecice.plugin.errors import CaseError
from gymprecice_openfoam import mesh, outputs, testing
from gymprecice_openfoam.installation import find_openfoam, run_tool

PATCHES = ["cylinder", "jet1", "jet2"]
RESOLUTION = 3.7  # about 16k cells


def _timeit(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def naive_geometry(mesh_dir: Path, names: list[str]) -> list[np.ndarray]:
    """Baseline: whole-file parse with foamlib's FoamFile and a Python loop per face."""
    points = FoamFile(mesh_dir / "points")[None]
    faces = FoamFile(mesh_dir / "faces")[None]
    if isinstance(faces, tuple):  # binary faceCompactList
        offsets, labels = faces
        faces = [labels[offsets[i] : offsets[i + 1]] for i in range(len(offsets) - 1)]
    boundary = dict(FoamFile(mesh_dir / "boundary")[None])
    out = []
    for name in names:
        start, size = boundary[name]["startFace"], boundary[name]["nFaces"]
        centres = []
        for face in faces[start : start + size]:
            pts = [tuple(points[i]) for i in face]
            n = len(pts)
            avg = [sum(p[k] for p in pts) / n for k in range(3)]
            sum_a, sum_ac = 0.0, [0.0, 0.0, 0.0]
            for i in range(n):
                p, q = pts[i], pts[(i + 1) % n]
                e = [q[k] - p[k] for k in range(3)]
                f = [avg[k] - p[k] for k in range(3)]
                cross = (
                    e[1] * f[2] - e[2] * f[1],
                    e[2] * f[0] - e[0] * f[2],
                    e[0] * f[1] - e[1] * f[0],
                )
                a = math.sqrt(sum(c * c for c in cross))
                sum_a += a
                for k in range(3):
                    sum_ac[k] += a * (p[k] + q[k] + avg[k])
            centres.append([c / (3 * sum_a) for c in sum_ac])
        out.append(np.array(centres))
    return out


def bench_geometry() -> None:
    try:
        inst = find_openfoam()
    except CaseError as exc:
        print(f"geometry: skipped ({str(exc).split('. Fix:')[0]})")
        return
    with tempfile.TemporaryDirectory() as tmp:
        print(
            f"geometry of {', '.join(PATCHES)} on a {testing.cylinder_cells(RESOLUTION)}-cell mesh"
        )
        print(
            f"  {'format':8} {'faces':>6} {'cold (s)':>10} {'warm (s)':>10} {'naive (s)':>10} {'speed-up':>9}"
        )
        for fmt in ("ascii", "binary"):
            case = testing.write_flow_case(
                Path(tmp) / fmt,
                testing.cylinder_block_mesh_dict(RESOLUTION),
                testing.CYLINDER_PATCHES,
                write_format=fmt,
                adapter=False,
            )
            run_tool(["blockMesh"], case, "log.blockMesh", inst)
            mesh_dir = case / "constant" / "polyMesh"

            def cold(mesh_dir: Path = mesh_dir) -> list[mesh.PatchGeometry]:
                mesh.clear_cache()
                return mesh.patch_geometry(mesh_dir, PATCHES)

            geoms = cold()
            t_cold = _timeit(cold, 7)
            t_warm = _timeit(lambda mesh_dir=mesh_dir: mesh.patch_geometry(mesh_dir, PATCHES), 20)
            baseline = naive_geometry(mesh_dir, PATCHES)
            t_naive = _timeit(lambda mesh_dir=mesh_dir: naive_geometry(mesh_dir, PATCHES), 3)
            for g, b in zip(geoms, baseline):
                assert np.allclose(g.centres, b, rtol=0, atol=1e-12), "baseline disagrees"
            faces = sum(len(g.centres) for g in geoms)
            print(
                f"  {fmt:8} {faces:6d} {t_cold:10.4f} {t_warm:10.6f} {t_naive:10.3f} "
                f"{t_naive / t_cold:8.1f}x"
            )
        print("  target: cold <= 0.1 s")


def _probe_file(path: Path, nprobes: int) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [f"# Probe {i} ({0.25 + 0.01 * i:g} 0.2 0.005)" for i in range(nprobes)]
    lines.append("#       Probe" + "".join(f"{i:>14}" for i in range(nprobes)))
    lines.append("#        Time")
    path.write_text("\n".join(lines) + "\n")


def _append_rows(path: Path, times: np.ndarray, rng: np.random.Generator, nprobes: int) -> None:
    values = rng.standard_normal((len(times), nprobes))
    text = "".join(
        f"{t:>13g}" + "".join(f"{v:>14.6g}" for v in row) + "\n" for t, row in zip(times, values)
    )
    with path.open("a") as handle:
        handle.write(text)


def naive_last_row(path: Path) -> np.ndarray:
    """Baseline: load the whole file every step (numpy's C reader) and keep the last row."""
    return np.loadtxt(path, comments="#", ndmin=2)[-1, 1:]


def bench_observations(nprobes: int = 151, per_step: int = 50, steps: int = 400) -> None:
    rng = np.random.default_rng(0)
    dt = 5e-4
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "probes" / "0" / "p"
        _probe_file(path, nprobes)
        reader = outputs.ProbesReader(path.parent.parent, "p")
        inc, naive = [], []
        checkpoints = {}
        for step in range(1, steps + 1):
            times = ((step - 1) * per_step + np.arange(1, per_step + 1)) * dt
            _append_rows(path, times, rng, nprobes)
            start = time.perf_counter()
            obs = reader.read_new().last
            inc.append(time.perf_counter() - start)
            if step in (1, steps // 10, steps // 2, steps):
                start = time.perf_counter()
                ref = naive_last_row(path)
                naive.append(time.perf_counter() - start)
                assert np.array_equal(obs, ref), "readers disagree"
                checkpoints[step] = (statistics.median(inc[-10:]), naive[-1])
        print(f"observation read per step: {nprobes} probes, {per_step} rows per step")
        print(
            f"  {'step':>6} {'rows in file':>12} {'incremental (ms)':>17} {'naive re-read (ms)':>19}"
        )
        for step, (t_inc, t_naive) in sorted(checkpoints.items()):
            print(f"  {step:6d} {step * per_step:12d} {t_inc * 1e3:17.3f} {t_naive * 1e3:19.3f}")
        print(
            f"  incremental mean over the episode: {statistics.mean(inc) * 1e3:.3f} ms "
            "(flat); the naive re-read grows with the file"
        )


def main() -> int:
    bench_geometry()
    print()
    bench_observations()
    return 0


if __name__ == "__main__":
    sys.exit(main())
