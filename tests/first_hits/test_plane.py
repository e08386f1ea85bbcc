"""plane_maxmip: bit-identical to the per-ray dda_maxmip (t, cell, normal) on batches of
vertical planes (one eye, one horizontal direction, many elevations; orthographic columns)
and on every other batch, and equal to the exact reference (the brute force) within the
first-hit tolerance. The hazards: terraces, grazing and lattice-aligned rays, vertical
rays, rays along grid lines and diagonals, eyes below the surface and far above it, rays
going up, per-ray tmin/tmax, rays that miss."""
import numpy as np
import pytest

import algos
from algos.render import default_camera
from datasets_gen import fields
from datasets_gen import rays as raysets

from ..helpers import first_hit_fields

SHAPE = (33, 41)  # (rows, cols)
OUTPUTS = ("t", "cell", "normal")


def _assert_identical(ref, got, o, d, what):
    """Bit for bit: t and normal as int64 bit patterns, cell exactly. The message is a
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
                f"dda_maxmip {name}={a[k]!r} plane_maxmip {name}={b[k]!r}")


def _check(fld, o, d, what, surfaces=algos.SURFACES, **kw):
    for surface in surfaces:
        ref = algos.intersect("dda_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                              threads=1, **kw)
        got = algos.intersect("plane_maxmip", fld, o, d, surface=surface, outputs=OUTPUTS,
                              threads=1, **kw)
        _assert_identical(ref, got, o, d, f"{what}, {surface}")


def _check_brute(H, o, d, what, surfaces=algos.SURFACES, tmin=None, tmax=None):
    """The exact reference: hit or miss alike, |dt| <= 1e-9 (1 + |t|)."""
    fld = algos.Field(H)
    for surface in surfaces:
        ref_t, _ = algos.brute_force_hits(H, o, d, surface, tmin=tmin, tmax=tmax)
        got = algos.intersect("plane_maxmip", fld, o, d, surface=surface, threads=1,
                              tmin=tmin, tmax=tmax).t
        hit_ref, hit_got = np.isfinite(ref_t), np.isfinite(got)
        both = hit_ref & hit_got
        far = np.zeros(len(got), bool)
        far[both] = np.abs(got[both] - ref_t[both]) > 1e-9 * (1 + np.abs(ref_t[both]))
        bad = np.union1d(np.nonzero(hit_ref != hit_got)[0], np.nonzero(far)[0])
        if len(bad):
            k = bad[0]
            raise AssertionError(
                f"{what}, {surface}: {len(bad)} rays differ from the brute force; first: "
                f"origin={o[k].tolist()!r} direction={d[k].tolist()!r} brute t={ref_t[k]!r} "
                f"plane_maxmip t={got[k]!r}")


def _fan(eye, directions2d, slopes, seed):
    """Every (eye, (dx, dy, dz)) for dz in slopes, shuffled (seeded): planes whose rays
    come in no particular order."""
    o, d = [], []
    for dx, dy in directions2d:
        for dz in slopes:
            o.append(eye)
            d.append((dx, dy, dz))
    o, d = np.array(o, dtype=float), np.array(d, dtype=float)
    order = np.random.default_rng(seed).permutation(len(o))
    return o[order], d[order]


def _directions(seed, n=12):
    """Horizontal directions: random azimuths, both axes both ways, the four diagonals,
    and lattice-aligned (integer) ones."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0, 2 * np.pi, n)
    random = np.stack([np.cos(a), np.sin(a)], axis=1)
    axes = np.array([(1, 0), (-1, 0), (0, 1), (0, -1)], float)
    diagonals = np.array([(1, 1), (-1, 1), (1, -1), (-1, -1)], float)
    lattice = np.array([(2, 1), (-3, 2), (1, -4), (5, 3)], float)
    return np.concatenate([random, axes, diagonals, lattice])


#: fans of slopes: steep to grazing, level, and going up, with repeats
SLOPES = np.concatenate([-np.geomspace(2.0, 1e-3, 14), [-1e-9, 0.0, 1e-9, 1e-3],
                         np.geomspace(1e-3, 0.5, 5), [-0.25, -0.25]])


def _eyes(H):
    """Eyes of every kind over an H of shape SHAPE: above the surface inside the
    footprint, at a grid vertex (rays on grid lines), outside the footprint, below the
    surface, far above the top (rays enter through the box's top at different t)."""
    rows, cols = H.shape
    top = float(H.max())
    return {
        "above": (12.3, 17.6, top + 0.5),
        "vertex": (20.0, 16.0, top + 0.25),
        "outside": (-3.5, -2.25, top * 0.5 + 1.0),
        "below": (9.5, 9.5, float(H[9, 9]) - 1.0),
        "high": (cols / 2 + 0.3, rows / 2 - 0.1, top + 40.0),
    }


@pytest.mark.parametrize("field_name", list(first_hit_fields(SHAPE)))
def test_plane_fans_equal_dda_maxmip(field_name):
    H = first_hit_fields(SHAPE)[field_name]
    fld = algos.Field(H)
    for k, (eye_name, eye) in enumerate(_eyes(H).items()):
        o, d = _fan(eye, _directions(k), SLOPES, seed=k)
        _check(fld, o, d, f"{field_name}, eye {eye_name}")


def test_plane_fans_equal_brute_force():
    """The fans against the exact reference, on the terraces, the spike and fBm, from
    every eye (the grid vertex's diagonal rays cross grid vertices exactly), every
    surface."""
    for field_name in ("terraces", "spike", "fbm"):
        H = first_hit_fields(SHAPE)[field_name]
        for k, (eye_name, eye) in enumerate(_eyes(H).items()):
            o, d = _fan(eye, _directions(k, n=3), SLOPES[::2], seed=k)
            _check_brute(H, o, d, f"{field_name}, eye {eye_name}")


def test_plane_tmin_tmax():
    """Per-ray tmin and tmax (seeded, some empty ranges): a ray starting later tests its
    own first cell; one ending before the hit cell walks alone."""
    H = first_hit_fields(SHAPE)["terraces"]
    fld = algos.Field(H)
    rng = np.random.default_rng(7)
    for k, eye in enumerate(_eyes(H).values()):
        o, d = _fan(eye, _directions(10 + k, n=4), SLOPES, seed=k)
        tmin = rng.choice([0.0, 0.0, 0.5, 3.0, 7.25], len(o))
        tmax = tmin + rng.choice([np.inf, np.inf, 2.0, 10.0, 0.0], len(o))
        _check(fld, o, d, f"tmin/tmax, eye {k}", tmin=tmin, tmax=tmax)
        _check_brute(H, o, d, f"tmin/tmax, eye {k}", tmin=tmin, tmax=tmax)


def test_vertical_rays_and_single_rays():
    """Vertical rays share no plane; rays alone in their plane; a mixed batch."""
    H = first_hit_fields(SHAPE)["uniform"]
    fld = algos.Field(H)
    eye = (12.5, 7.25, float(H.max()) + 1.0)
    o = np.array([eye] * 6 + [(3.0, 4.0, 9.0), (5.5, 6.5, 7.0)], float)
    d = np.array([(0, 0, -1), (0, 0, 1), (0, 0, -3), (1, 0, -0.5), (1, 0, -0.25),
                  (1, 0, 0.1), (0.3, 0.7, -0.2), (-1, 0, -1)], float)
    _check(fld, o, d, "vertical and single rays")
    _check_brute(H, o, d, "vertical and single rays")


def test_orthographic_columns():
    """Parallel rays whose origins share (x, y) and differ in z: each column of an
    orthographic camera (and the same rays shuffled)."""
    H = fields.generate("fbm", (65, 80), seed=9, amplitude=12.0, scale=24.0)
    fld = algos.Field(H)
    position, look_at = default_camera(H)
    rs = raysets.orthographic_camera(position, look_at, 50.0, 48, 27)
    _check(fld, rs.origins, rs.directions, "orthographic")
    order = np.random.default_rng(3).permutation(len(rs.origins))
    _check(fld, rs.origins[order], rs.directions[order], "orthographic, shuffled")
    o = np.array([(10.25, 20.5, z) for z in np.linspace(-3.0, 30.0, 25)])
    d = np.tile([0.6, 0.8, -0.3], (len(o), 1))
    _check(fld, o, d, "one column of heights")
    _check_brute(H, o, d, "one column of heights", surfaces=("triangles", "plane3"))


def test_level_camera_equals_dda_maxmip_and_resumes():
    """The level camera's columns are planes: identical outputs, and the chained walks
    visit fewer cells than the per-ray ones (the resumption ran)."""
    H = fields.generate("fbm", (129, 150), seed=5, amplitude=20.0, scale=32.0)
    fld = algos.Field(H)
    position, look_at = default_camera(H)
    position = np.array([10.5, 12.25, float(H.max()) * 0.8])
    rs = raysets.level_camera(position, look_at, 70.0, 64, 36)
    assert len({(a, b) for a, b in rs.directions[:, :2].tolist()}) == 64
    _check(fld, rs.origins, rs.directions, "level camera")
    ref = algos.intersect("dda_maxmip", fld, rs.origins, rs.directions, outputs=("stats",))
    got = algos.intersect("plane_maxmip", fld, rs.origins, rs.directions, outputs=("stats",))
    assert got.stats["cells_visited"].sum() < 0.8 * ref.stats["cells_visited"].sum()


def test_threads_and_hazards():
    """The first-hit hazards (no shared planes to speak of) and a threaded level camera."""
    H = first_hit_fields(SHAPE)["terraces"]
    fld = algos.Field(H)
    rs = raysets.first_hit_hazards((SHAPE[1] - 1, SHAPE[0] - 1), 29, per_family=40)
    _check(fld, rs.origins, rs.directions, "hazards")
    position, look_at = default_camera(H)
    cam = raysets.level_camera(position, look_at, 60.0, 40, 24)
    one = algos.intersect("plane_maxmip", fld, cam.origins, cam.directions, threads=1)
    two = algos.intersect("plane_maxmip", fld, cam.origins, cam.directions, threads=2)
    assert np.array_equal(one.t.view(np.int64), two.t.view(np.int64))


@pytest.mark.parametrize("projection", ["level", "orthographic"])
def test_render_same_image(projection):
    H = fields.generate("fbm", (97, 97), seed=2, amplitude=15.0, scale=24.0)
    a = algos.render(H, "dda_maxmip", width=48, height=27, projection=projection, threads=1)
    b = algos.render(H, "plane_maxmip", width=48, height=27, projection=projection, threads=1)
    assert np.isfinite(a.depth).any() and not np.isfinite(a.depth).all()
    assert np.array_equal(a.depth.view(np.int64), b.depth.view(np.int64))
    assert np.array_equal(a.cell, b.cell)
    assert np.array_equal(a.rgb, b.rgb)


def test_render_rejects_unknown_projection():
    H = fields.generate("flat", (9, 9), height=1.0)
    with pytest.raises(ValueError, match="projection"):
        algos.render(H, "dda_maxmip", width=4, height=3, projection="fisheye")
    with pytest.raises(ValueError, match="projection"):
        algos.render(H, "zbuffer", width=4, height=3, projection="level")


def test_camera_rays_shapes_and_errors():
    rs = raysets.level_camera((0.0, 0.0, 5.0), (10.0, 3.0, 1.0), 60.0, 8, 5)
    assert rs.origins.shape == rs.directions.shape == (40, 3)
    cols = rs.directions.reshape(5, 8, 3)
    assert (cols[:, :, :2] == cols[:1, :, :2]).all()  # one (dx, dy) per column
    assert (np.diff(cols[:, 0, 2]) < 0).all()  # rows top down
    centre_slope = (1.0 - 5.0) / np.hypot(10.0, 3.0)
    assert np.isclose(cols[:, :, 2].mean(), centre_slope)
    ortho = raysets.orthographic_camera((0.0, 0.0, 5.0), (10.0, 3.0, 1.0), 60.0, 8, 5)
    o = ortho.origins.reshape(5, 8, 3)
    assert (o[:, :, :2] == o[:1, :, :2]).all() and (np.diff(o[:, 0, 2]) < 0).all()
    assert np.allclose(np.linalg.norm(ortho.directions, axis=1), 1.0)
    with pytest.raises(ValueError, match="look_at"):
        raysets.level_camera((1.0, 1.0, 5.0), (1.0, 1.0, 0.0), 60.0, 8, 5)
    with pytest.raises(ValueError, match="fov"):
        raysets.orthographic_camera((0.0, 0.0, 5.0), (10.0, 3.0, 1.0), 180.0, 8, 5)


def test_hit_cell_entered_at_t1_is_not_resumed():
    """A pinned case: a ray whose range ends exactly where the ray below entered its hit
    cell (a grid vertex, flat walls). Its walk stops in the cell it leaves at t1, so the
    chain must not resume it in the cell entered; p(t1) is then decided after the walk by
    the cell entered (docs/CONVENTIONS.md, "Points on a cell border"), whose wall it meets:
    a hit at t1 in that cell, as over the longer range of the ray below."""
    H = first_hit_fields(SHAPE)["terraces"]
    o = np.array([(20.0, 16.0, 4.0)] * 2)
    d = np.array([(1.0, 1.0, -0.25)] * 2)
    tmin, tmax = np.array([0.5, 0.0]), np.array([np.inf, 2.0])
    fld = algos.Field(H)
    _check(fld, o, d, "hit cell entered at t1", tmin=tmin, tmax=tmax)
    got = algos.intersect("plane_maxmip", fld, o, d, surface="flat", tmin=tmin, tmax=tmax)
    assert got.t[0] == 2.0 and got.t[1] == 2.0
    assert tuple(got.cell[0]) == tuple(got.cell[1])
    t, cell = algos.brute_force_hits(H, o, d, "flat", tmin=tmin, tmax=tmax)
    assert t.tolist() == [2.0, 2.0] and (cell == got.cell).all()


def test_seeded_random_planes():
    """Seeded random planes over random small fields: eyes anywhere (outside, below,
    above), origins on and off the quarter lattice, unit and integer directions, repeated
    and shuffled heights and slopes, per-ray tmin/tmax on half the batches; every surface
    against dda_maxmip, bit for bit."""
    rng = np.random.default_rng(2026)
    for it in range(120):
        rows, cols = (int(v) for v in rng.integers(3, 30, 2))
        kind = ("fbm", "terraces", "uniform", "flat")[it % 4]
        if kind == "uniform":
            H = rng.integers(0, 4, (rows, cols)).astype(float)
        elif kind == "flat":
            H = np.full((rows, cols), float(rng.integers(0, 3)))
        else:
            H = fields.generate(kind, (rows, cols), seed=it, amplitude=5.0, scale=8.0)
        o, d = [], []
        for _ in range(int(rng.integers(1, 5))):
            ox, oy = rng.uniform(-3, cols + 2), rng.uniform(-3, rows + 2)
            if rng.random() < 0.5:
                ox, oy = np.round(ox * 4) / 4, np.round(oy * 4) / 4
            if rng.random() < 0.6:
                a = rng.uniform(0, 2 * np.pi)
                dx, dy = np.cos(a), np.sin(a)
            else:
                dx, dy = (float(v) for v in rng.integers(-3, 4, 2))
                dx = dx if (dx, dy) != (0.0, 0.0) else 1.0
            oz0 = rng.uniform(-2, float(H.max()) + 6)
            for _ in range(int(rng.integers(2, 20))):
                oz = oz0 if rng.random() < 0.7 else oz0 + rng.choice([-1.0, 0.5, 2.0])
                dz = rng.choice([rng.uniform(-2, 0.5), -rng.uniform(0, 1e-3), 0.0, -0.25])
                o.append((ox, oy, oz))
                d.append((dx, dy, dz))
        o, d = np.array(o), np.array(d)
        kw = {}
        if it % 2:
            tmin = rng.choice([0.0, 0.0, 1.5, 4.0], len(o))
            kw = dict(tmin=tmin, tmax=tmin + rng.choice([np.inf, 3.0, 9.0, 0.0], len(o)))
        _check(algos.Field(H), o, d, f"random planes, iteration {it}, {kind} {H.shape}", **kw)


def _image(eye, directions2d, slopes, top_down=True):
    """Rays laid out as a row-major image whose columns are planes, as the level camera
    gives them: column c has direction directions2d[c], row r slope slopes[r], rows from
    the steepest up (top_down) or from the lowest; every origin is ``eye``."""
    slopes = np.sort(np.asarray(slopes, dtype=float))
    slopes = slopes[::-1] if top_down else slopes
    dirs = np.asarray(directions2d, dtype=float)
    rows, width = len(slopes), len(dirs)
    d = np.empty((rows, width, 3))
    d[:, :, :2] = dirs[None, :, :]
    d[:, :, 2] = slopes[:, None]
    o = np.broadcast_to(np.asarray(eye, dtype=float), (rows * width, 3)).copy()
    return o, d.reshape(-1, 3)


def test_image_layout_equals_dda_maxmip():
    """Batches in an image's layout (the column path: no grouping, each column traced
    bottom up), listed top down and bottom up, from every eye (above, on a grid vertex,
    outside the footprint, below the surface, far above), with rays going up, level and
    down, against dda_maxmip bit for bit and against the brute force."""
    for field_name in ("terraces", "fbm", "spike"):
        H = first_hit_fields(SHAPE)[field_name]
        fld = algos.Field(H)
        for k, (eye_name, eye) in enumerate(_eyes(H).items()):
            for top_down in (True, False):
                o, d = _image(eye, _directions(20 + k, n=5), SLOPES, top_down)
                what = f"image, {field_name}, eye {eye_name}, top_down={top_down}"
                _check(fld, o, d, what)
                if top_down:
                    _check_brute(H, o, d, what, surfaces=("flat", "triangles"))


def test_image_layout_tmin_tmax_and_misses():
    """The column path with per-ray tmin and tmax (later starts, ends before the hit
    cell, empty ranges), and columns that pass over the terrain (every ray a miss)."""
    H = first_hit_fields(SHAPE)["terraces"]
    fld = algos.Field(H)
    rng = np.random.default_rng(31)
    for k, eye in enumerate(_eyes(H).values()):
        o, d = _image(eye, _directions(40 + k, n=4), SLOPES)
        tmin = rng.choice([0.0, 0.0, 0.5, 3.0, 7.25], len(o))
        tmax = tmin + rng.choice([np.inf, np.inf, 2.0, 10.0, 0.0], len(o))
        _check(fld, o, d, f"image tmin/tmax, eye {k}", tmin=tmin, tmax=tmax)
        _check_brute(H, o, d, f"image tmin/tmax, eye {k}", tmin=tmin, tmax=tmax)
    top = float(H.max())
    o, d = _image((2.5, 3.5, top + 5.0), _directions(50, n=3), np.geomspace(1e-6, 1e-2, 9))
    hits = algos.intersect("plane_maxmip", fld, o, d)
    assert np.isinf(hits.t).all()
    _check(fld, o, d, "image of misses")


def test_image_layout_broken_and_degenerate():
    """Batches that start like an image but are not one further down (rays of other
    planes, vertical rays and a shuffled column in later rows: each such ray is traced
    alone, the others still chained), duplicated rays and rows, a single column, a
    single row (every plane of one ray), and an orthographic image whose columns differ
    in oz only."""
    H = first_hit_fields(SHAPE)["fbm"]
    fld = algos.Field(H)
    eye = _eyes(H)["above"]
    dirs = _directions(60, n=4)
    o, d = _image(eye, dirs, SLOPES)
    width = len(dirs)
    rng = np.random.default_rng(61)
    broken_o, broken_d = o.copy(), d.copy()
    rows = rng.choice(np.arange(2, len(o) // width), 6, replace=False)
    for r in rows[:3]:  # another plane's ray
        broken_d[r * width + 1, :2] = (0.3, -0.9)
    for r in rows[3:5]:  # a vertical ray
        broken_d[r * width + 2] = (0.0, 0.0, -1.0)
    broken_o[rows[5] * width + 3, :2] += 0.5  # another origin
    _check(fld, broken_o, broken_d, "image broken below its first rows")
    column = np.arange(width, len(o), width)  # column 0 but its first ray, shuffled
    shuffled = np.arange(len(o))
    shuffled[column] = rng.permutation(column)
    _check(fld, o[shuffled], d[shuffled], "image with a column out of order")
    twice_o = np.repeat(o.reshape(-1, width, 3), 2, axis=0).reshape(-1, 3)
    twice_d = np.repeat(d.reshape(-1, width, 3), 2, axis=0).reshape(-1, 3)
    _check(fld, twice_o, twice_d, "image with every row twice")
    same_o, same_d = np.tile(o[:width], (5, 1)), np.tile(d[:width], (5, 1))
    _check(fld, same_o, same_d, "image of one row repeated")
    one_o, one_d = _image(eye, dirs[:1], SLOPES)
    _check(fld, one_o, one_d, "one column")
    _check(fld, o[:width], d[:width], "one row: planes of one ray")
    ortho_o = np.array([(10.25, 20.5, z) for z in np.linspace(30.0, -3.0, 25)])
    ortho_o = np.repeat(ortho_o, 3, axis=0)
    ortho_o[1::3, 0] += 1.5
    ortho_o[2::3, 1] -= 2.25
    ortho_d = np.tile([0.6, 0.8, -0.3], (len(ortho_o), 1))
    _check(fld, ortho_o, ortho_d, "orthographic image, three columns")


def test_image_layout_resumes():
    """The column path chains its rays: on a level camera it visits fewer cells than
    dda_maxmip, and so does the same image listed bottom up."""
    H = fields.generate("fbm", (129, 150), seed=5, amplitude=20.0, scale=32.0)
    fld = algos.Field(H)
    _, look_at = default_camera(H)
    rs = raysets.level_camera((10.5, 12.25, float(H.max()) * 0.8), look_at, 70.0, 64, 36)
    up = np.arange(len(rs.origins)).reshape(36, 64)[::-1].reshape(-1)
    for what, o, d in (("top down", rs.origins, rs.directions),
                       ("bottom up", rs.origins[up], rs.directions[up])):
        _check(fld, o, d, f"level camera, {what}")
        ref = algos.intersect("dda_maxmip", fld, o, d, outputs=("stats",), threads=1)
        got = algos.intersect("plane_maxmip", fld, o, d, outputs=("stats",), threads=1)
        assert got.stats["cells_visited"].sum() < 0.8 * ref.stats["cells_visited"].sum(), what


def test_image_layout_partial_rows():
    """A share of an image (what a thread gets): starting inside a row, ending inside
    one, and the whole image on 1, 2, 3 and 7 threads; every way against dda_maxmip."""
    H = fields.generate("fbm", (97, 97), seed=4, amplitude=15.0, scale=24.0)
    fld = algos.Field(H)
    position, look_at = default_camera(H)
    rs = raysets.level_camera(position, look_at, 60.0, 37, 21)
    o, d = rs.origins, rs.directions
    for lo, hi in ((5, len(o)), (0, len(o) - 11), (40, len(o) - 3), (36, 36 + 2 * 37),
                   (3, 3 + 2 * 37 + 1)):
        _check(fld, o[lo:hi], d[lo:hi], f"image rays {lo}:{hi}")
    ref = algos.intersect("dda_maxmip", fld, o, d, outputs=OUTPUTS, threads=1)
    for threads in (2, 3, 7):
        got = algos.intersect("plane_maxmip", fld, o, d, outputs=OUTPUTS, threads=threads)
        _assert_identical(ref, got, o, d, f"image on {threads} threads")
