"""The floor walk (cext/hierarchies/maxmip.h, hf_floor_walk) keeps the current cell's exit
faces and steps them on the axis it moves along, while dda builds each cell's interval
from scratch (hf_cell_interval). Every kernel built on that walk must give dda's t, cell
and normal bit for bit on the rays where the faces are delicate: through grid vertices
(the two exit faces tie and both axes step), with a zero, -0 or subnormal component (an
axis not moved on, or faces at +-inf from hf_inverse's +-DBL_MAX), from far off the grid,
and starting on grid lines (a face at -0 for a ray moving back). Written by carry10 for a
floor walk that carried its cells' intervals too (measured at about 1 % fewer
instructions on dda_maxmip and +0.3 % on packet_maxmip, and not merged); it guards the
walk as it is."""
import numpy as np
import pytest

import algos

from ..helpers import first_hit_fields

SHAPE = (33, 41)  # rows, cols
#: the kernels whose cells go through hf_floor_walk, with options that vary its tiles
FLOOR_WALKS = [("dda_maxmip", {}), ("dda_maxmip", dict(fine_level=0)),
               ("dda_maxmip", dict(fine_level=5)), ("dda_maxmip", dict(cull_cells=False)),
               ("packet_maxmip", dict(packet_width=8)), ("plane_maxmip", {}),
               ("ring_maxmip", {}), ("pitched_maxmip", {}), ("dda_compact", {})]
TINY = (5e-324, -5e-324, 1e-310, -1e-310, 0.0, -0.0, 1e-20, -1e-20)


def _face_rays(seed, n=360):
    """n rays, six kinds in turn: diagonals, one tiny component (either axis), slopes p/q,
    far origins, any direction; origins on grid vertices or lines for most."""
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = SHAPE
    o, d = [], []
    for k in range(n):
        x = float(rng.integers(0, cols - 1)) + (0.0 if k % 2 else rng.uniform(0, 1))
        y = float(rng.integers(0, rows - 1)) + (0.0 if k % 3 else rng.uniform(0, 1))
        z = rng.uniform(-1, 10)
        a, b = rng.choice([-1.0, 1.0]), rng.choice([-1.0, 1.0])
        kind = k % 6
        if kind == 0:  # a diagonal through grid vertices: mx == my at every vertex
            dx, dy = a, b
        elif kind == 1:
            dx, dy = a, float(rng.choice(TINY))
        elif kind == 2:
            dx, dy = float(rng.choice(TINY)), b
        elif kind == 3:  # slopes p/q: vertices now and then
            dx, dy = a * rng.integers(1, 4), b * rng.integers(1, 4)
        elif kind == 4:  # from far off along x
            x = float(rng.choice([-1.0, 1.0]) * 2.0 ** rng.integers(10, 30))
            y = rng.uniform(-4, rows + 4)
            dx, dy = -np.sign(x), rng.normal() * 1e-3
        else:
            dx, dy = rng.normal(), rng.normal()
        dz = -rng.uniform(0, 0.5) if k % 5 else rng.uniform(0, 0.2)
        o.append((x, y, z))
        d.append((dx, dy, dz))
    return np.array(o), np.array(d)


@pytest.fixture(scope="module")
def reference():
    """dda's t, cell and normal per (field, surface, tmin) on the face rays."""
    o, d = _face_rays(10)
    out = {}
    for fname, H in first_hit_fields(SHAPE).items():
        fld = algos.Field(H)
        for surface in algos.SURFACES:
            for tmin in (None, 0.5):
                hits = algos.intersect("dda", fld, o, d, surface=surface, tmin=tmin,
                                       outputs=("t", "cell", "normal"))
                out[(fname, surface, tmin)] = (fld, hits)
    return o, d, out


@pytest.mark.parametrize("name,options", FLOOR_WALKS, ids=lambda v: str(v) if v else "")
def test_carried_faces_give_dda_bit_for_bit(name, options, reference):
    o, d, cases = reference
    for (fname, surface, tmin), (fld, want) in cases.items():
        if surface not in algos.INTERSECTOR_REGISTRY[name].surfaces:
            continue
        got = algos.intersect(name, fld, o, d, surface=surface, tmin=tmin,
                              outputs=("t", "cell", "normal"), **options)
        for output in ("t", "cell", "normal"):
            w, g = getattr(want, output), getattr(got, output)
            same = (w.view(np.uint8).reshape(len(w), -1) == g.view(np.uint8).reshape(len(g), -1))
            bad = np.nonzero(~same.all(axis=1))[0]
            if len(bad):
                k = int(bad[0])
                raise AssertionError(
                    f"{name} {options} on {fname}/{surface}, tmin={tmin}: {len(bad)} rays' "
                    f"{output} differ from dda's; first: origin={o[k].tolist()!r} "
                    f"direction={d[k].tolist()!r} dda {w[k]!r}, got {g[k]!r}")
