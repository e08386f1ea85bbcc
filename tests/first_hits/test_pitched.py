"""pitched_maxmip: bit-identical to the per-ray dda_maxmip (t, cell, normal) on pinhole
cameras at any pitch, equal to the exact reference (the brute force) within the first-hit
tolerance, and its per-ray lower bound on the hit never above the exact t. The cameras:
at the field's edge, outside it, looking straight down, looking up (few or no hits),
grazing (2.6 degrees of pitch), over terraces (flat tops on the lattice), with rays along
grid lines, and an eye below the surface; plus batches without a shared origin (the
fallback) and a threaded call."""
import math

import numpy as np
import pytest

import algos
from algos import _kernels
from algos.intersect import prepare_intersect
from datasets_gen import rays as raysets

from ..helpers import first_hit_fields

SHAPE = (33, 41)  # (rows, cols)
OUTPUTS = ("t", "cell", "normal")
FIELDS = first_hit_fields(SHAPE)


def _look(position, pitch_deg, azimuth_deg=30.0, distance=10.0):
    """The point `distance` ahead of `position` at `pitch_deg` below the horizontal,
    along a heading of `azimuth_deg` from +x towards +y."""
    a, p = math.radians(azimuth_deg), math.radians(pitch_deg)
    x, y, z = position
    return (x + distance * math.cos(p) * math.cos(a), y + distance * math.cos(p) * math.sin(a),
            z - distance * math.sin(p))


def _cameras(H):
    """(name, origins, directions) of every camera over field H (heights about 0 .. 8)."""
    top = float(H.max())
    rows, cols = H.shape
    cams = {
        "grazing": ((3.25, 4.5, top + 0.6), _look((3.25, 4.5, top + 0.6), 2.6)),
        "pitched": ((5.5, 2.25, top + 4.0), _look((5.5, 2.25, top + 4.0), 25.0, 50.0)),
        "edge": ((0.0, 0.0, top + 1.5), _look((0.0, 0.0, top + 1.5), 12.0, 40.0)),
        "far_edge": ((cols - 1.0, rows - 1.0, top + 2.0),
                     _look((cols - 1.0, rows - 1.0, top + 2.0), 15.0, 215.0)),
        "outside": ((-12.0, -7.5, top + 3.0), _look((-12.0, -7.5, top + 3.0), 8.0, 35.0)),
        "down": ((17.3, 11.6, top + 9.0), (17.3, 11.6, 0.0)),
        "up": ((20.5, 15.5, top + 0.25), _look((20.5, 15.5, top + 0.25), -30.0, 80.0)),
        "below": ((20.5, 15.5, -1.0), _look((20.5, 15.5, -1.0), 20.0, 10.0)),
    }
    out = []
    for name, (position, look_at) in cams.items():
        rs = raysets.pinhole(position, look_at, 70.0, 24, 14)
        out.append((name, rs.origins, rs.directions))
    # a camera on the lattice looking along +x and +y: rays along grid lines and diagonals
    eye = np.array([4.0, 6.0, float(H[6, 4]) + 2.0])
    d = []
    for dx, dy in ((1, 0), (0, 1), (1, 1), (2, 1), (1, 2), (1, 0.5)):
        for dz in (-0.5, -0.25, -0.125, -0.0625, -1 / 64):
            d.append((dx, dy, dz))
    out.append(("grid_lines", np.tile(eye, (len(d), 1)), np.array(d, dtype=float)))
    return out


def _assert_identical(ref, got, o, d, what):
    """Bit for bit: t and normal as int64 bit patterns, cell exactly; the message is a
    reproducer."""
    checks = [("t", ref.t.view(np.int64), got.t.view(np.int64)),
              ("cell", ref.cell, got.cell),
              ("normal", ref.normal.view(np.int64), got.normal.view(np.int64))]
    for name, a, b in checks:
        differ = np.nonzero((a != b).reshape(len(a), -1).any(axis=1))[0]
        if len(differ):
            k = differ[0]
            raise AssertionError(
                f"{what}: {len(differ)} of {len(a)} rays differ in {name}; first: ray {k}, "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} "
                f"dda_maxmip {name}={a[k]!r} pitched_maxmip {name}={b[k]!r}")


def _bounds(H, o, d, surface):
    """pitched_maxmip's t and the parameter each ray's walk was allowed to start from."""
    fld = algos.Field(H)
    algorithm = algos.INTERSECTOR_REGISTRY["pitched_maxmip"]
    run = prepare_intersect(algorithm, fld, surface, np.ascontiguousarray(o, float),
                            np.ascontiguousarray(d, float), None, None, ("t",),
                            dict(algorithm.options), 1)
    bound = np.empty(len(o))
    _kernels.intersect_pitched_bounds(bound, *run.args)
    return run.t, bound


@pytest.mark.parametrize("field_name", sorted(FIELDS))
def test_identical_to_dda_maxmip(field_name):
    H = FIELDS[field_name]
    fld = algos.Field(H)
    for name, o, d in _cameras(H):
        for surface in algos.SURFACES:
            ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                                  threads=1)
            got = algos.intersect("pitched_maxmip", fld, o, d, surface=surface,
                                  outputs=OUTPUTS, threads=1)
            _assert_identical(ref, got, o, d, f"{field_name}, {name}, {surface}")


@pytest.mark.parametrize("field_name", ["fbm", "terraces", "spike"])
def test_brute_force_and_bound(field_name):
    """Hits equal the brute force's (|dt| <= 1e-9 (1 + |t|)), and the bound is at most the
    exact t on every ray that hits (inf only where the brute force misses)."""
    H = FIELDS[field_name]
    used = 0
    for name, o, d in _cameras(H):
        for surface in algos.SURFACES:
            ref_t, _ = algos.brute_force_hits(H, o, d, surface)
            got, bound = _bounds(H, o, d, surface)
            hit_ref, hit_got = np.isfinite(ref_t), np.isfinite(got)
            both = hit_ref & hit_got
            far = np.zeros(len(got), bool)
            far[both] = np.abs(got[both] - ref_t[both]) > 1e-9 * (1 + np.abs(ref_t[both]))
            bad = np.union1d(np.nonzero(hit_ref != hit_got)[0], np.nonzero(far)[0])
            # at most the kernel's own t, and the exact t within the first-hit tolerance
            # (a ray that hits where it enters gets t0, which may round an ulp apart)
            limit = np.minimum(np.where(hit_got, got, np.inf),
                               ref_t + 1e-9 * (1 + np.abs(ref_t)))
            above = np.nonzero(hit_ref & ~(bound <= limit))[0]
            for k, what in ((bad, "differs from the brute force"), (above, "bound above t")):
                if len(k):
                    k = k[0]
                    raise AssertionError(
                        f"{field_name}, {name}, {surface}: ray {what}: origin={o[k].tolist()!r} "
                        f"direction={d[k].tolist()!r} brute t={ref_t[k]!r} "
                        f"pitched_maxmip t={got[k]!r} bound={bound[k]!r}")
            used += int(np.sum(hit_ref & (bound > 0)))
    assert used > 0, "no camera gave any ray a bound above 0"


def test_bound_moves_the_start():
    """On a pitched camera over fBm the walk starts later: fewer tiles tested than
    dda_maxmip, with the same hits; looking up past the top, every ray misses without a
    walk."""
    H = FIELDS["fbm"]
    fld = algos.Field(H)
    position = (3.25, 4.5, float(H.max()) + 0.6)
    rs = raysets.pinhole(position, _look(position, 2.6), 60.0, 48, 27)
    ref = algos.intersect("dda_maxmip", fld, rs.origins, rs.directions, outputs=("t", "stats"))
    got = algos.intersect("pitched_maxmip", fld, rs.origins, rs.directions,
                          outputs=("t", "stats"))
    assert np.array_equal(ref.t.view(np.int64), got.t.view(np.int64))
    work = [h.stats["cells_visited"].sum() + h.stats["tiles_skipped"].sum() for h in (ref, got)]
    assert work[1] < work[0]
    position = (20.5, 15.5, float(H.max()) + 0.25)
    rs = raysets.pinhole(position, _look(position, -45.0), 40.0, 16, 9)
    t, bound = _bounds(H, rs.origins, rs.directions, "triangles")
    assert not np.isfinite(t).any()
    assert np.isinf(bound).all()


def test_fallbacks_and_threads():
    """A batch without one shared origin walks like dda_maxmip; so do threads."""
    H = FIELDS["terraces"]
    fld = algos.Field(H)
    rs = raysets.first_hit_hazards((SHAPE[1] - 1, SHAPE[0] - 1), 29, per_family=40)
    for surface in algos.SURFACES:
        ref = algos.intersect("dda_maxmip", fld, rs.origins, rs.directions, surface=surface,
                              outputs=OUTPUTS)
        got = algos.intersect("pitched_maxmip", fld, rs.origins, rs.directions,
                              surface=surface, outputs=OUTPUTS)
        _assert_identical(ref, got, rs.origins, rs.directions, f"hazards, {surface}")
    position = (5.5, 2.25, float(H.max()) + 4.0)
    cam = raysets.pinhole(position, _look(position, 25.0, 50.0), 60.0, 40, 24)
    one = algos.intersect("pitched_maxmip", fld, cam.origins, cam.directions, threads=1)
    two = algos.intersect("pitched_maxmip", fld, cam.origins, cam.directions, threads=2)
    assert np.array_equal(one.t.view(np.int64), two.t.view(np.int64))


def test_rejects_bad_input():
    H = FIELDS["flat"]
    o = np.array([[1.0, 1.0, 5.0]])
    with pytest.raises(ValueError, match="direction"):
        algos.intersect("pitched_maxmip", H, o, np.array([[np.nan, 0.0, -1.0]]))
    with pytest.raises(ValueError, match="bound"):
        _kernels.intersect_pitched_bounds(
            np.empty(1), algos.INTERSECTOR_REGISTRY["dda_maxmip"].kernel_id,
            *prepare_intersect(algos.INTERSECTOR_REGISTRY["dda_maxmip"], algos.Field(H),
                               "triangles", o, np.array([[0.5, 0.0, -1.0]]), None, None,
                               ("t",), dict(cull_cells=True, fine_level=3), 1).args[1:])


def test_render_same_image():
    """algos.render with the pinhole (the default projection) draws dda_maxmip's image."""
    from datasets_gen import fields

    H = fields.generate("fbm", (97, 97), seed=2, amplitude=15.0, scale=24.0)
    a = algos.render(H, "dda_maxmip", width=48, height=27, threads=1)
    b = algos.render(H, "pitched_maxmip", width=48, height=27, threads=1)
    assert np.isfinite(a.depth).any()
    assert np.array_equal(a.depth.view(np.int64), b.depth.view(np.int64))
    assert np.array_equal(a.cell, b.cell)
    assert np.array_equal(a.rgb, b.rgb)


@pytest.mark.parametrize("seed", range(6))
def test_random_eyes_identical(seed):
    """Seeded random eyes (inside, above, outside and far from the field), random fans of
    directions around a random heading, random per-ray tmin >= 0 and tmax: bit for bit
    dda_maxmip's, on every field and surface; the bound never above the hit."""
    rng = np.random.default_rng(seed)
    bounded = 0
    for field_name, H in FIELDS.items():
        fld = algos.Field(H)
        rows, cols = H.shape
        top = float(H.max())
        eye = np.array([rng.uniform(-20, cols + 20), rng.uniform(-20, rows + 20),
                        top + rng.choice([0.01, 0.5, 3.0, 40.0]) * rng.uniform(0.5, 1.5)])
        heading = np.array([cols / 2, rows / 2, 0.0]) - eye
        heading[2] = -np.linalg.norm(heading[:2]) * np.tan(np.radians(rng.uniform(-10, 80)))
        n = 300
        d = heading / np.linalg.norm(heading) + rng.normal(scale=rng.uniform(0.05, 0.8),
                                                           size=(n, 3))
        o = np.tile(eye, (n, 1))
        tmin = np.where(rng.random(n) < 0.3, rng.uniform(0, 20, n), 0.0)
        tmax = np.where(rng.random(n) < 0.3, tmin + rng.uniform(0, 60, n), np.inf)
        for surface in algos.SURFACES:
            ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                                  tmin=tmin, tmax=tmax, threads=1)
            got = algos.intersect("pitched_maxmip", fld, o, d, surface=surface,
                                  outputs=OUTPUTS, tmin=tmin, tmax=tmax, threads=1)
            _assert_identical(ref, got, o, d, f"seed {seed}, {field_name}, {surface}")
        t, bound = _bounds(H, o, d, "triangles")
        ref = algos.intersect("dda_maxmip", fld, o, d, threads=1).t
        assert np.all(bound <= ref), (seed, field_name, eye.tolist())
        bounded += int(np.sum((bound > 0) & np.isfinite(ref)))
    assert bounded > 0, "no ray that hits was given a bound above 0"


def test_many_boxes_fall_back():
    """fine_level=0 on a 700^2 field asks for more boxes than a small batch is worth: the
    bound is dropped (every ray walks from t0) and the hits stay dda_maxmip's."""
    from datasets_gen import fields

    H = fields.generate("fbm", (700, 700), seed=5, amplitude=30.0, scale=64.0)
    fld = algos.Field(H)
    position = (10.5, 20.25, float(H.max()) + 3.0)
    rs = raysets.pinhole(position, _look(position, 6.0, 40.0), 50.0, 16, 9)
    ref = algos.intersect("dda_maxmip", fld, rs.origins, rs.directions, outputs=OUTPUTS,
                          fine_level=0)
    got = algos.intersect("pitched_maxmip", fld, rs.origins, rs.directions, outputs=OUTPUTS,
                          fine_level=0)
    _assert_identical(ref, got, rs.origins, rs.directions, "fine_level=0")
    # no bound: every ray took dda_maxmip's very walk, so the work counts agree too
    ref, got = (algos.intersect(k, fld, rs.origins, rs.directions, outputs=("stats",),
                                fine_level=0) for k in ("dda_maxmip", "pitched_maxmip"))
    for name in ("cells_visited", "tiles_skipped"):
        assert np.array_equal(ref.stats[name], got.stats[name]), name


def test_sky_and_side_wall_rays():
    """The rays that skip the box clip (level or rising, tmin >= 0, meeting no box) and
    the descending rays that must not: rays from outside the field that pass below hmin
    before they reach its side hit the side wall at a single parameter, below every tile
    box. Both camera halves, with tmin 0, positive and negative, give dda_maxmip's
    outputs bit for bit."""
    H = FIELDS["fbm"]
    fld = algos.Field(H)
    rows, cols = H.shape
    hmin, top = float(H.min()), float(H.max())
    # eye outside the -x side, looking at the field level with the side's bottom: the
    # lower rows pass hmin before x = 0, the upper rows rise over the field
    position = (-6.0, rows / 2, hmin + 0.3 * (top - hmin))
    rs = raysets.pinhole(position, (cols / 2, rows / 2, hmin + 0.3 * (top - hmin)), 100.0, 40,
                         30)
    o, d = rs.origins, rs.directions
    ref = algos.intersect("dda_maxmip", fld, o, d, outputs=OUTPUTS, threads=1)
    z = o[:, 2] + ref.t * d[:, 2]
    assert np.sum(np.isfinite(ref.t) & (z < hmin)) > 0, "no ray hits the side below hmin"
    assert np.sum(~np.isfinite(ref.t) & (d[:, 2] > 0)) > 0, "no rising ray misses"
    for tmin in (None, 0.5, -2.0):
        lo = None if tmin is None else np.full(len(o), tmin)
        ref = algos.intersect("dda_maxmip", fld, o, d, tmin=lo, outputs=OUTPUTS, threads=1)
        got = algos.intersect("pitched_maxmip", fld, o, d, tmin=lo, outputs=OUTPUTS, threads=1)
        _assert_identical(ref, got, o, d, f"side wall and sky, tmin={tmin}")
