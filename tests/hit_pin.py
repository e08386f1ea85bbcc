"""Fixed first-hit cases whose outputs are pinned bit for bit (tests/data/hit_pin.npz).

The pin was written by the kernels as they stood before the tight first-hit loops
(the tuning round): tuning may make a kernel faster, never change its t or
its cell. Exact kernels must keep them forever; a float kernel may change only by a
deliberate, documented change, which regenerates the pin:

    python -m tests.hit_pin --write      # then say why in the commit

``packet_maxmip`` was added to the pin with ``dda_maxmip``'s pinned arrays,
copied, not recomputed: it must equal them bit for bit.
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
    args = parser.parse_args(argv)
    result = compute()
    if args.write:
        np.savez_compressed(PIN, **result)
        print(f"wrote {len(result)} arrays to {PIN}")


if __name__ == "__main__":
    main()
