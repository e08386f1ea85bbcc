"""Instructions per ray of ``plane_maxmip`` against ``dda_maxmip`` on a level camera,
counted with callgrind (docs/plane.md, "Instructions per ray").

Each kernel runs in its own process under ``valgrind --tool=callgrind --branch-sim=yes
--cache-sim=yes``, with the fixed cache model of ``bench.studies.compact`` (32 KiB 8-way
D1, 8 MiB 16-way LL, 64-byte lines, so the counts do not depend on the host),
collecting only inside the C batch entry, on the same rays: a 640 x 360 level camera
(``datasets_gen.rays.level_camera``, 60 degrees) low over an fBm field, looking at its
centre at mid-height. Counts do not depend on machine load, so they may be taken on a
busy machine; this module times nothing.

    python -m bench.studies.plane_counts [--size 2048] [--width 640] [--height 360]
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile

import numpy as np

from .compact import CACHE  # the simulated caches: (bytes, ways, line bytes)

KERNELS = ("dda_maxmip", "plane_maxmip")
ENTRY = "hf_intersect_batch"



def camera_rays(size: int, width: int, height: int):
    """(field, origins, directions) of the counted batch: fBm size^2 (seed 1), eye at
    (-0.02 size, -0.02 size, hmax + 0.01 size), looking at the centre at mid-height."""
    import algos
    from datasets_gen import fields
    from datasets_gen import rays as raysets

    H = fields.generate("fbm", (size, size), seed=1)
    field = algos.Field(H)
    hmin, hmax = float(H.min()), float(H.max())
    position = (-0.02 * size, -0.02 * size, hmax + 0.01 * size)
    look_at = (size / 2, size / 2, hmin + 0.5 * (hmax - hmin))
    rs = raysets.level_camera(position, look_at, 60.0, width, height)
    return field, rs.origins, rs.directions


def _trace(kernel: str, size: int, width: int, height: int) -> None:
    """The counted process: build everything, then one traced call."""
    import algos

    field, o, d = camera_rays(size, width, height)
    field.mip_for()
    hits = algos.intersect(kernel, field, o, d, outputs=("t",), threads=1)
    print(f"{kernel}: {np.isfinite(hits.t).mean():.4f} of the rays hit")


def _totals(path: str) -> dict:
    """The event totals of a callgrind output file."""
    events, totals = None, None
    with open(path) as f:
        for line in f:
            if line.startswith("events:"):
                events = line.split()[1:]
            elif line.startswith("totals:") or line.startswith("summary:"):
                totals = [int(v) for v in line.split()[1:]]
    return dict(zip(events or (), totals or ()))


def count(kernel: str, size=2048, width=640, height=360) -> dict:
    """{Ir, Bc, Bcm, D1mr, DLmr, ...} per ray of one kernel on the batch of
    :func:`camera_rays` (callgrind's event names)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cache = [f"--{name}={','.join(str(v) for v in CACHE[name])}" for name in ("I1", "D1", "LL")]
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
               f"--toggle-collect={ENTRY}", "--branch-sim=yes", "--cache-sim=yes", *cache,
               "--dump-instr=no", "--collect-jumps=no", sys.executable, "-m",
               "bench.studies.plane_counts", "--trace", kernel, "--size", str(size),
               "--width", str(width), "--height", str(height)]
        subprocess.run(cmd, check=True, capture_output=True)
        totals = _totals(out)
    rays = width * height
    return {k: v / rays for k, v in totals.items()}


def main(argv=None) -> int:
    """Count plane_maxmip and dda_maxmip on a level camera under callgrind; print the table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=2048)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--trace", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.trace:
        _trace(args.trace, args.size, args.width, args.height)
        return 0
    print("| kernel | instructions / ray | conditional branches / ray | mispredicted / ray "
          "| D1 misses / ray | LL misses / ray |")
    print("|---|---|---|---|---|---|")
    for kernel in KERNELS:
        c = count(kernel, args.size, args.width, args.height)
        d1 = c.get("D1mr", 0) + c.get("D1mw", 0)
        ll = c.get("DLmr", 0) + c.get("DLmw", 0)
        print(f"| `{kernel}` | {c.get('Ir', 0):.0f} | {c.get('Bc', 0):.0f} | "
              f"{c.get('Bcm', 0):.1f} | {d1:.2f} | {ll:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
