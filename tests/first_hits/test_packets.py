"""packet_maxmip: bit-identical to the per-ray dda_maxmip (t, cell, normal and statistics)
on camera batches, parallel batches and the first-hit hazards, at every packet width, and
equal to the exact reference (the brute force) within the first-hit tolerance."""
import numpy as np
import pytest

import algos
from algos.render import default_camera
from datasets_gen import fields
from datasets_gen import rays as raysets

from ..helpers import first_hit_fields

WIDTHS = (1, 2, 4, 8)
OUTPUTS = ("t", "cell", "normal", "stats")


def _assert_identical(ref, got, o, d, what):
    """Bit for bit: t and normal compared as int64 bit patterns (so -0.0, NaN payloads and
    inf all count), cell and every statistic exactly. The message is a reproducer."""
    checks = [("t", ref.t.view(np.int64), got.t.view(np.int64)),
              ("cell", ref.cell, got.cell),
              ("normal", ref.normal.view(np.int64), got.normal.view(np.int64))]
    checks += [(k, ref.stats[k], got.stats[k]) for k in ref.stats]
    for name, a, b in checks:
        differ = np.nonzero((a != b).reshape(len(a), -1).any(axis=1))[0]
        if len(differ):
            k = differ[0]
            raise AssertionError(
                f"{what}: {len(differ)} of {len(a)} rays differ in {name}; first: ray {k}, "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} "
                f"dda_maxmip {name}={a[k]!r} packet_maxmip {name}={b[k]!r}")


def _check_against_dda_maxmip(fld, o, d, what, surfaces=algos.SURFACES, widths=WIDTHS, **kw):
    for surface in surfaces:
        ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                              threads=1, **kw)
        for width in widths:
            got = algos.intersect("packet_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                                  threads=1, packet_width=width, **kw)
            _assert_identical(ref, got, o, d, f"{what}, {surface}, packet_width={width}")


def _check_against_brute(H, fld, o, d, what, surfaces=algos.SURFACES):
    """The exact reference: hit or miss alike, |dt| <= 1e-9 (1 + |t|)."""
    for surface in surfaces:
        ref_t, _ = algos.brute_force_hits(H, o, d, surface)
        got = algos.intersect("packet_maxmip", fld, o, d, surface=surface, threads=1).t
        hit_ref, hit_got = np.isfinite(ref_t), np.isfinite(got)
        bad = np.nonzero(hit_ref != hit_got)[0]
        both = hit_ref & hit_got
        far = np.zeros(len(got), bool)
        far[both] = np.abs(got[both] - ref_t[both]) > 1e-9 * (1 + np.abs(ref_t[both]))
        bad = np.union1d(bad, np.nonzero(far)[0])
        if len(bad):
            k = bad[0]
            raise AssertionError(
                f"{what}, {surface}: {len(bad)} rays differ from the brute force; first: "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} brute t={ref_t[k]!r} "
                f"packet_maxmip t={got[k]!r}")


def _random_cameras(H, seed, count, width, height):
    """Pinhole batches from seeded random cameras: above the field, around it and low over
    it (grazing views), looking at random points of the footprint."""
    rng = np.random.Generator(np.random.PCG64(seed))
    rows, cols = H.shape
    lo, hi = float(H.min()), float(H.max())
    for _ in range(count):
        where = rng.integers(0, 3)
        if where == 0:  # above the footprint
            pos = [rng.uniform(0, cols - 1), rng.uniform(0, rows - 1), hi + rng.uniform(1, 30)]
        elif where == 1:  # outside it, looking in
            pos = [rng.uniform(-0.5, 1.5) * cols, rng.uniform(-0.5, 1.5) * rows,
                   hi + rng.uniform(-2, 20)]
        else:  # low: grazing rays
            pos = [rng.uniform(0, cols - 1), rng.uniform(0, rows - 1), rng.uniform(lo, hi + 1)]
        look = [rng.uniform(0, cols - 1), rng.uniform(0, rows - 1), rng.uniform(lo, hi)]
        if np.allclose(np.subtract(look, pos)[:2], 0):
            look[0] += 1.0
        rs = raysets.pinhole(np.array(pos), np.array(look), rng.uniform(20, 100), width, height)
        yield rs.origins, rs.directions


@pytest.mark.parametrize("shape", [(33, 41), (64, 64), (70, 129)])
def test_camera_batches(shape):
    """Random pinhole cameras; 13 x 7 = 91 rays per image (not a multiple of 2, 4 or 8)."""
    H = fields.generate("fbm", shape, seed=shape[1], amplitude=8.0, scale=12.0)
    fld = algos.Field(H)
    for k, (o, d) in enumerate(_random_cameras(H, seed=shape[0], count=6, width=13, height=7)):
        _check_against_dda_maxmip(fld, o, d, f"camera {k} on fbm {shape}")
        _check_against_brute(H, fld, o, d, f"camera {k} on fbm {shape}")


def test_render_camera_is_identical():
    """The default camera of ``algos.render``, at an image size that leaves a short last
    packet, on every fine level (0: tiles of one cell)."""
    H = fields.generate("fbm", (97, 97), seed=5, amplitude=20.0, scale=30.0)
    fld = algos.Field(H)
    pos, look = default_camera(H)
    # on the diagonal x = y the middle column's rays cross grid vertices exactly: the
    # brute force enters the diagonal cell there, as the kernels do (docs/CONVENTIONS.md,
    # "Points on a cell border"); off it, on every fine level
    rs = raysets.pinhole(pos + np.array([0.3, 0.0, 0.0]), look, 60.0, 45, 23)
    diagonal = raysets.pinhole(pos, look, 60.0, 45, 23)
    _check_against_dda_maxmip(fld, diagonal.origins, diagonal.directions, "render, diagonal")
    _check_against_brute(H, fld, diagonal.origins, diagonal.directions, "render, diagonal")
    for fine_level in (0, 1, 3, 30):
        _check_against_dda_maxmip(fld, rs.origins, rs.directions, f"render, fine_level={fine_level}",
                                  widths=(4, 8), fine_level=fine_level)
    _check_against_brute(H, fld, rs.origins, rs.directions, "render")


@pytest.mark.parametrize("direction,elevation", [
    ((3.0, 1.0), 5.0),      # sun shadow rays, a shallow sun
    ((-1.0, -2.5), 30.0),
    ((0.0, 1.0), 10.0),     # axis-parallel: rays on grid lines take the per-ray path
    ((1.0, 1.0), 0.5),      # the diagonal, grazing
    ((7.0, -0.001), 45.0),  # almost axis-parallel
])
def test_parallel_batches(direction, elevation):
    """Orthographic batches: one direction, origins inside and around the footprint, in
    the generator's order (neighbours in a packet are not neighbours on the ground)."""
    H = fields.generate("fbm", (50, 61), seed=3, amplitude=8.0, scale=10.0)
    fld = algos.Field(H)
    for origins in ("inside", "around"):
        rs = raysets.parallel(203, (49, 60), seed=11, direction=direction, origins=origins,
                              height=float(H.max()) + 2.0, elevation=elevation)
        what = f"parallel {direction} at {elevation} deg, origins {origins}"
        _check_against_dda_maxmip(fld, rs.origins, rs.directions, what)
        _check_against_brute(H, fld, rs.origins, rs.directions, what)


def test_parallel_grid_of_origins():
    """An orthographic camera's rays: a regular grid of origins, neighbours in a packet."""
    H = fields.generate("fbm", (64, 64), seed=8, amplitude=10.0, scale=16.0)
    fld = algos.Field(H)
    # (spacing and slope chosen so that no ray crosses a grid vertex exactly: see
    # test_render_camera_is_identical)
    u, v = np.meshgrid(np.linspace(-10, 40, 19) + 0.0137, np.linspace(-5, 50, 11) + 0.0291)
    o = np.column_stack([u.ravel(), v.ravel(), np.full(u.size, float(H.max()) + 5)])
    d = np.tile([0.8, 0.4537, -0.3], (len(o), 1))
    _check_against_dda_maxmip(fld, o, d, "orthographic grid")
    _check_against_brute(H, fld, o, d, "orthographic grid")


@pytest.mark.parametrize("fname", ["fbm", "terraces", "uniform", "spike", "flat", "tilted"])
def test_first_hit_hazards(fname):
    """Grazing, steep, vertical (on vertices), starting inside the solid, along grid lines,
    entering through the sides: packed together as they come."""
    shape = (33, 41)
    H = first_hit_fields(shape)[fname]
    fld = algos.Field(H)
    rs = raysets.first_hit_hazards(shape, seed=29, per_family=37,
                                   families=raysets.HAZARD_FAMILIES[:6])
    _check_against_dda_maxmip(fld, rs.origins, rs.directions, f"hazards on {fname}")
    _check_against_brute(H, fld, rs.origins, rs.directions, f"hazards on {fname}")


def test_packets_that_diverge_at_once():
    """Every packet holds rays in opposite and crossing directions from one point, and
    rays that miss (upwards, or beside the footprint) between rays that hit."""
    H = fields.generate("fbm", (40, 40), seed=4, amplitude=6.0, scale=9.0)
    fld = algos.Field(H)
    rng = np.random.Generator(np.random.PCG64(77))
    n = 157
    centre = np.column_stack([rng.uniform(5, 34, n), rng.uniform(5, 34, n),
                              np.full(n, float(H.max()) + 1)])
    angle = rng.uniform(0, 2 * np.pi, n) + np.pi * (np.arange(n) % 2)
    d = np.column_stack([np.cos(angle), np.sin(angle), -rng.uniform(0.0, 0.3, n)])
    d[3::5, 2] = 0.2  # upwards: misses
    o = centre.copy()
    o[4::7, :2] += 100.0  # beside the footprint: misses (the box clip)
    hits = algos.intersect("packet_maxmip", fld, o, d, threads=1)
    assert np.isfinite(hits.t).any() and not np.isfinite(hits.t).all()
    _check_against_dda_maxmip(fld, o, d, "diverging packets")
    _check_against_brute(H, fld, o, d, "diverging packets")


def test_tmin_tmax_and_threads():
    """Per-ray ranges cut walks at different points of a packet; threads split the batch
    (packets are formed within each part): outputs still identical."""
    H = fields.generate("fbm", (64, 64), seed=9, amplitude=10.0, scale=16.0)
    fld = algos.Field(H)
    pos, look = default_camera(H)
    rs = raysets.pinhole(pos, look, 50.0, 31, 17)
    rng = np.random.Generator(np.random.PCG64(12))
    n = len(rs.origins)
    tmin = rng.uniform(0, 40, n)
    tmax = tmin + rng.uniform(0, 80, n)
    _check_against_dda_maxmip(fld, rs.origins, rs.directions, "tmin/tmax", tmin=tmin, tmax=tmax)
    one = algos.intersect("packet_maxmip", fld, rs.origins, rs.directions, outputs=OUTPUTS,
                          threads=1)
    two = algos.intersect("packet_maxmip", fld, rs.origins, rs.directions, outputs=OUTPUTS,
                          threads=2)
    _assert_identical(one, two, rs.origins, rs.directions, "threads=2")


def test_render_takes_packet_maxmip():
    H = fields.generate("fbm", (48, 48), seed=2, amplitude=8.0, scale=12.0)
    a = algos.render(H, "dda_maxmip", width=24, height=13, threads=1)
    b = algos.render(H, "packet_maxmip", width=24, height=13, threads=1)
    assert np.isfinite(a.depth).any()
    assert np.array_equal(a.depth.view(np.int64), b.depth.view(np.int64))
    assert np.array_equal(a.cell, b.cell)
    assert np.array_equal(a.normal.view(np.int64), b.normal.view(np.int64))


@pytest.mark.parametrize("width", [0, 3, 16, 4.0, True])
def test_bad_packet_width(width):
    H = fields.generate("fbm", (16, 16), seed=1)
    with pytest.raises(ValueError, match="packet_width"):
        algos.intersect("packet_maxmip", H, [[1.0, 1.0, 50.0]], [[1.0, 0.5, -1.0]],
                        packet_width=width)


def test_packet_width_is_packet_maxmip_only():
    H = fields.generate("fbm", (16, 16), seed=1)
    with pytest.raises(ValueError, match="packet_width"):
        algos.intersect("dda_maxmip", H, [[1.0, 1.0, 50.0]], [[1.0, 0.5, -1.0]], packet_width=4)


def test_the_coherence_study_runs(tmp_path):
    """bench.studies.packets on a small field and image: every coherence, both kernels,
    bit-identical, ns/ray measured (its callgrind counts run the machinery of
    bench.regress.instructions_gate, tested in test_regress_counts.py; off here)."""
    from bench.studies import packets

    rows = packets.run(str(tmp_path / "p"), datasets=(("fbm", 64),), image=(24, 10),
                       counts=False, repeats=1, echo=lambda *_: None)
    assert {x["coherence"] for x in rows} == set(packets.COHERENCE)
    assert all(x["identical"] for x in rows)
    assert all(x["ns_per_ray"] > 0 and x["rays"] == 240 for x in rows)
    assert (tmp_path / "p" / "tables.md").read_text().count("| fbm64 |") == len(rows)
    with pytest.raises(ValueError, match="coherence"):
        packets.batch(algos.Field(fields.generate("fbm", (16, 16), seed=1)), "nope")

