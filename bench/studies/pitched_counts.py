"""Instructions per ray of ``pitched_maxmip`` against ``dda_maxmip`` on a pitched pinhole
camera, counted with callgrind (docs/pitched.md, "Instructions per ray").

Each kernel runs in its own process under ``valgrind --tool=callgrind --branch-sim=yes``,
collecting only inside the C batch entries (``hf_intersect_batch``, ``hf_pitched_batch``:
the coarse image is counted with the walks), on the same rays: a 640 x 360 pinhole
(``datasets_gen.rays.pinhole``, 60 degrees) over an fBm field, its eye as in
:mod:`bench.studies.plane_counts`, heading for the field's centre and pitched down by
``--pitch`` degrees (2.6 by default: a grazing view). Counts do not depend on machine
load, so they may be taken on a busy machine; this module times nothing.

    python -m bench.studies.pitched_counts [--size 2048] [--width 640] [--height 360] [--pitch 2.6]
"""
from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile

import numpy as np

from .plane_counts import _totals

KERNELS = ("dda_maxmip", "pitched_maxmip")
ENTRIES = ("hf_intersect_batch", "hf_pitched_batch")


def camera_rays(size: int, width: int, height: int, pitch: float):
    """(field, origins, directions) of the counted batch: fBm size^2 (seed 1), eye at
    (-0.02 size, -0.02 size, hmax + 0.01 size), heading for the field's centre, pitched
    down by ``pitch`` degrees."""
    import algos
    from datasets_gen import fields
    from datasets_gen import rays as raysets

    H = fields.generate("fbm", (size, size), seed=1)
    field = algos.Field(H)
    hmax = float(H.max())
    position = (-0.02 * size, -0.02 * size, hmax + 0.01 * size)
    heading = np.array([size / 2 - position[0], size / 2 - position[1]])
    heading /= np.linalg.norm(heading)
    p = math.radians(pitch)
    look_at = (position[0] + heading[0] * math.cos(p), position[1] + heading[1] * math.cos(p),
               position[2] - math.sin(p))
    rs = raysets.pinhole(position, look_at, 60.0, width, height)
    return field, rs.origins, rs.directions


def _trace(kernel: str, size: int, width: int, height: int, pitch: float) -> None:
    """The counted process: build everything, then one traced call."""
    import algos

    field, o, d = camera_rays(size, width, height, pitch)
    field.mip_for()
    hits = algos.intersect(kernel, field, o, d, outputs=("t",), threads=1)
    print(f"{kernel}: {np.isfinite(hits.t).mean():.4f} of the rays hit")


def count(kernel: str, size=2048, width=640, height=360, pitch=2.6) -> dict:
    """{Ir, Bc, Bcm, ...} per ray of one kernel on the batch of :func:`camera_rays`."""
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "callgrind.out")
        cmd = ["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}",
               *(f"--toggle-collect={entry}" for entry in ENTRIES), "--branch-sim=yes",
               sys.executable, "-m", "bench.studies.pitched_counts", "--trace", kernel,
               "--size", str(size), "--width", str(width), "--height", str(height),
               "--pitch", str(pitch)]
        subprocess.run(cmd, check=True, capture_output=True)
        totals = _totals(out)
    rays = width * height
    return {k: v / rays for k, v in totals.items()}


def main(argv=None) -> int:
    """Count pitched_maxmip and dda_maxmip on a pitched pinhole under callgrind; print the
    table."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=2048)
    parser.add_argument("--width", type=int, default=640)
    parser.add_argument("--height", type=int, default=360)
    parser.add_argument("--pitch", type=float, default=2.6,
                        help="degrees below the horizontal")
    parser.add_argument("--trace", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.trace:
        _trace(args.trace, args.size, args.width, args.height, args.pitch)
        return 0
    print("| kernel | instructions / ray | conditional branches / ray | mispredicted / ray |")
    print("|---|---|---|---|")
    for kernel in KERNELS:
        c = count(kernel, args.size, args.width, args.height, args.pitch)
        print(f"| `{kernel}` | {c.get('Ir', 0):.0f} | {c.get('Bc', 0):.0f} | "
              f"{c.get('Bcm', 0):.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
