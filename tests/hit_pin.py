"""Fixed first-hit cases whose outputs are pinned bit for bit (tests/data/hit_pin.npz).

The pin was written by the kernels as they stood before the tight first-hit loops
(the tuning round): tuning may make a kernel faster, never change its t or
its cell. Exact kernels must keep them forever; a float kernel may change only by a
deliberate, documented change, which regenerates the pin:

    python -m tests.hit_pin --write      # then say why in the commit

``packet_maxmip`` was added to the pin with ``dda_maxmip``'s pinned arrays,
copied, not recomputed: it must equal them bit for bit. ``plane_maxmip`` joined the same
way, with two groups of vertical planes added for every kernel (a level camera and an
orthographic camera over the fBm field), whose ``dda_maxmip`` arrays it was given too;
``pitched_maxmip`` joined the same way, with a group of one pitched pinhole camera over
the fBm field (its eye shared by every ray, bit for bit), pinned for every kernel.
``ring_maxmip`` joined the same way, on the existing groups (no new group).
``python -m tests.hit_pin --add`` adds missing arrays and never rewrites a pinned one.
"""
from __future__ import annotations

import argparse
import os

import numpy as np

import algos
from datasets_gen import fields
from datasets_gen import rays as raysets
from datasets_gen.rays import first_hit_rays

from .helpers import first_hit_fields

PIN = os.path.join(os.path.dirname(__file__), "data", "hit_pin.npz")
#: Every C intersector; the peer (Embree) is not ours to pin.
KERNELS = tuple(n for n, a in algos.INTERSECTOR_REGISTRY.items() if a.kind != "peer")
#: Kernels whose t and cell equal dda_maxmip's bit for bit, pinned with its arrays.
SAME_AS_DDA_MAXMIP = ("packet_maxmip", "plane_maxmip", "pitched_maxmip", "ring_maxmip")
EXACT = tuple(n for n in KERNELS if algos.INTERSECTOR_REGISTRY[n].accuracy == "exact")


def cases():
    """(label, heights, origins, directions) of every pinned group."""
    shape = (33, 41)
    small = first_hit_fields(shape)
    rs = raysets.first_hit_hazards(shape, 29, per_family=40)
    o, d = rs.origins, rs.directions
    out = [(name, H, o, d) for name, H in small.items()]
    # bench-like rays on a field big enough for several mip levels and long runs
    H = fields.generate("fbm", (257, 300), seed=7, amplitude=40.0, scale=64.0)
    fld = algos.Field(H)
    for r in (1, 3, 25, 100):
        o, d = first_hit_rays(fld, r, 150, seed=11 + r)
        out.append((f"fbm257-r{r}", H, o, d))
    # vertical planes: image columns of a level and an orthographic camera, low over fBm
    position, look_at = (12.5, 20.25, float(H.max()) * 0.7), (200.0, 150.0, float(H.mean()))
    for camera in (raysets.level_camera, raysets.orthographic_camera):
        rs = camera(position, look_at, 60.0, 32, 18)
        out.append((f"fbm257-{rs.params['kind']}", H, rs.origins, rs.directions))
    # one eye: a pinhole pitched down about 19 degrees (no two rays share a vertical plane)
    rs = raysets.pinhole(position, (position[0] + 0.7, position[1] + 0.5, position[2] - 0.3),
                         60.0, 32, 18)
    out.append(("fbm257-pinhole", H, rs.origins, rs.directions))
    return out


def compute():
    """{key: array} of t and cell for every (case, surface, kernel)."""
    result = {}
    for label, H, o, d in cases():
        fld = algos.Field(H)
        for surface in algos.SURFACES:
            for name in KERNELS:
                if surface not in algos.INTERSECTOR_REGISTRY[name].surfaces:
                    continue
                hits = algos.intersect(name, fld, o, d, surface=surface, outputs=("t", "cell"))
                result[f"{label}/{surface}/{name}/t"] = hits.t
                result[f"{label}/{surface}/{name}/cell"] = hits.cell
    return result


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--write", action="store_true", help="rewrite the pin")
    parser.add_argument("--add", action="store_true",
                        help="add the arrays the pin lacks (a kernel whose outputs must equal "
                             "dda_maxmip's gets dda_maxmip's pinned arrays); keep every other")
    args = parser.parse_args(argv)
    result = compute()
    if args.write:
        np.savez_compressed(PIN, **result)
        print(f"wrote {len(result)} arrays to {PIN}")
    elif args.add:
        with np.load(PIN) as data:
            pinned = {k: data[k] for k in data.files}
        added = 0
        for key, value in result.items():
            if key in pinned:
                continue
            label, surface, name, output = key.split("/")
            twin = f"{label}/{surface}/dda_maxmip/{output}"
            pinned[key] = pinned.get(twin, value) if name in SAME_AS_DDA_MAXMIP else value
            added += 1
        np.savez_compressed(PIN, **pinned)
        print(f"added {added} arrays to {PIN}")


if __name__ == "__main__":
    main()
