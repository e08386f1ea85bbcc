"""A ray's outputs are its own, whatever rays come before it in the batch.

The C dispatcher sets up one hit record per batch (or per packet slot, ring slot, plane)
and lets it serve every ray in turn: each ray's set-up clears the result and the
statistics and rewrites only the fields that depend on the ray (cext/dispatch/intersect.c,
ray_begin). So a field a ray forgot to rewrite would carry the ray before it into its
outputs. Here every C kernel, on every surface, traces a batch and the same rays in a
seeded shuffled order, bit for bit alike: t, cell, normal and (but for the kernels whose
work depends on the batch by design) the statistics. The rays mix hits, misses of the
box (and rays that end at a tmax on a grid line just after one, which border_point
reads), single-point ranges, rays on grid lines, vertical rays and starts inside.
"""
import numpy as np
import pytest

import algos
from datasets_gen import rays as raysets

from ..helpers import first_hit_fields

SHAPE = (17, 19)  # (rows, cols)
#: every C intersector (the peer, Embree, is not ours)
KERNELS = tuple(n for n, a in algos.INTERSECTOR_REGISTRY.items() if a.kind != "peer")
#: kernels whose statistics depend on the batch by design: a plane's rays resume the walks
#: of the rays below (plane_maxmip), a camera's coarse image comes from all its rays
#: (pitched_maxmip)
BATCH_STATS = ("plane_maxmip", "pitched_maxmip")


def _rays():
    """Hazard rays of every family, rays that miss the box, and per-ray ranges: a third
    end at a tmax on the grid line x = 4 (where the ray crosses it, when it does), a
    fifth start at tmin = -3."""
    rows, cols = SHAPE
    rs = raysets.first_hit_hazards(SHAPE, 41, per_family=12, families=raysets.HAZARD_FAMILIES)
    rng = np.random.Generator(np.random.PCG64(43))
    k = 24
    away = np.column_stack([rng.uniform(-30, -5, k), rng.uniform(0, rows, k),
                            rng.uniform(0, 9, k)])
    o = np.vstack([rs.origins, away])
    d = np.vstack([rs.directions, np.column_stack([-rng.uniform(0.5, 2, k),
                                                   rng.normal(size=k), rng.normal(size=k)])])
    n = len(o)
    tmin = np.where(rng.random(n) < 0.2, -3.0, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        on_line = (4.0 - o[:, 0]) / d[:, 0]
    tmax = np.where((rng.random(n) < 0.33) & (on_line > tmin), on_line, np.inf)
    return o, d, tmin, tmax


@pytest.mark.parametrize("surface", algos.SURFACES)
@pytest.mark.parametrize("kernel", KERNELS)
def test_outputs_do_not_depend_on_the_rays_before(kernel, surface):
    if surface not in algos.INTERSECTOR_REGISTRY[kernel].surfaces:
        pytest.skip(f"{kernel} has no {surface} surface")
    o, d, tmin, tmax = _rays()
    order = np.random.Generator(np.random.PCG64(47)).permutation(len(o))
    outputs = ("t", "cell", "normal", "stats")
    for name, heights in first_hit_fields(SHAPE).items():
        fld = algos.Field(heights)
        one = algos.intersect(kernel, fld, o, d, surface=surface, tmin=tmin, tmax=tmax,
                              outputs=outputs)
        other = algos.intersect(kernel, fld, o[order], d[order], surface=surface,
                                tmin=tmin[order], tmax=tmax[order], outputs=outputs)
        checks = [("t", one.t.view(np.int64)[order], other.t.view(np.int64)),
                  ("cell", one.cell[order], other.cell),
                  ("normal", one.normal.view(np.int64)[order], other.normal.view(np.int64))]
        if kernel not in BATCH_STATS:
            checks += [(f"stats {s}", one.stats[s][order], other.stats[s]) for s in one.stats]
        for what, a, b in checks:
            differ = np.nonzero((a != b).reshape(len(a), -1).any(axis=1))[0]
            if len(differ):
                k = int(order[differ[0]])
                raise AssertionError(
                    f"{kernel} on {surface} {name}: {len(differ)} rays differ in {what} when "
                    f"shuffled; first: origin={o[k].tolist()!r} direction={d[k].tolist()!r} "
                    f"tmin={tmin[k]!r} tmax={tmax[k]!r}: {a[differ[0]]!r} != {b[differ[0]]!r}")
