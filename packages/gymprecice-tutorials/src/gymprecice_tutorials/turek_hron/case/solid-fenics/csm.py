"""Turek and Hron's structural tests of the bar alone: CSM1 and CSM2 (static, under
gravity) and CSM3 (the free oscillation under gravity from rest).

    python csm.py CSM1 --out csm1.json [--cells 36,4] [--degree 2]
    python csm.py CSM3 --out csm3.json [--time-step 0.005] [--end 10]

Writes point A's displacement as JSON: the static one, or the series ``time``, ``dx``,
``dy``. Runs in the FEniCS solver environment's interpreter; the comparison with the
published values is gymprecice_tutorials.turek_hron.solid_checks.
"""

import argparse
import json
import os
import time

from bar import CSM, FSI3, Bar

#: each test's bar and its gravity, m/s^2 (Turek & Hron 2006, table 3)
TESTS = {"CSM1": (CSM, 2.0), "CSM2": (FSI3, 2.0), "CSM3": (CSM, 2.0)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("test", choices=sorted(TESTS))
    parser.add_argument("--out", required=True)
    parser.add_argument("--cells", default="36,4", help="rectangles along x,y")
    parser.add_argument("--degree", type=int, default=2)
    parser.add_argument("--time-step", type=float, default=0.005)
    parser.add_argument("--end", type=float, default=10.0)
    parser.add_argument("--save-at", type=float, default=None, help="CSM3: save the state then")
    parser.add_argument("--state", default=None, help="CSM3: where --save-at saves, or start from")
    args = parser.parse_args()
    material, gravity = TESTS[args.test]
    nx, ny = (int(n) for n in args.cells.split(","))
    bar = Bar(material, (nx, ny), args.degree, gravity=gravity)
    started = time.monotonic()
    record = {"test": args.test, "cells": [nx, ny], "degree": args.degree, "dofs": bar.V.dim()}
    if args.test != "CSM3":
        bar.solve_static()
        record["dx"], record["dy"] = bar.tip()
    else:
        if args.state and args.save_at is None:
            bar.load(args.state)
        series = {"time": [bar.time], "dx": [bar.tip()[0]], "dy": [bar.tip()[1]]}
        steps = round((args.end - bar.time) / args.time_step)
        for _ in range(steps):
            bar.step(args.time_step)
            bar.advance(args.time_step)
            dx, dy = bar.tip()
            series["time"].append(bar.time)
            series["dx"].append(dx)
            series["dy"].append(dy)
            if args.save_at is not None and abs(bar.time - args.save_at) < args.time_step / 2:
                bar.save(args.state)
        record.update(series, time_step=args.time_step)
    record["wall_clock_s"] = round(time.monotonic() - started, 1)
    tmp = args.out + ".tmp"
    with open(tmp, "w") as handle:
        json.dump(record, handle)
    os.replace(tmp, args.out)


if __name__ == "__main__":
    main()
