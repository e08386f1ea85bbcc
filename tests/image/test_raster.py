"""The rasterisers (algos.raster, cext/raster/raster.c) against the exact tracers.

- zbuffer, painter, watkins and warnock draw the triangles surface; an exact intersector
  (``dda``, whose triangle test is exact up to float64 rounding) on the same primary rays
  is the reference. They must agree on every pixel except where the pixel centre lies within
  rounding of a projected triangle edge; those pixels are counted and checked to be such.
- Watertightness: with one sheet of surface in view, every pixel the tracer hits gets
  exactly one front-facing fragment (no cracks, no double hits), every other pixel none.
- floating_horizon: within its documented bound for a level camera on a plane, a ridge
  and a spike.
- Bad cameras, empty views and 1x1 images: clear errors or empty images.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from algos import raster

# 1e-6 pixel: a centre this close to a projected edge is "within rounding" of it (the
# rounding of a projection is about 1e-13 pixel at these sizes; the margin is generous)
EDGE_PIXELS = 1e-6


def random_field(seed, rows=33, cols=40, relief=4.0):
    rng = np.random.default_rng(seed)
    return (rng.random((rows, cols)) * relief).astype(np.float32)


# (name, position, look_at): an overview from outside the field (skirts in view), a view
# from inside looking across, a grazing view near the ground, a view from a corner
VIEWS = [
    ("overview", (-5.0, -6.0, 20.0), (20.0, 16.0, 1.0)),
    ("inside", (20.0, 15.0, 8.0), (5.0, 30.0, 2.0)),
    ("grazing", (-3.0, 10.0, 5.0), (30.0, 12.0, 1.5)),
    ("corner", (45.0, 40.0, 6.0), (10.0, 5.0, 0.0)),
]


def _camera(position, look_at, fov, width, height):
    frame, sx, sy = raster.pinhole_frame(position, look_at, fov, width, height)
    return frame, sx, sy


def _project(frame, width, height, points):
    """Pixel coordinates (X, Y) of world points (..., 3), as cext/raster/raster.c projects."""
    p, f, r, u = frame[:3], frame[3:6], frame[6:9], frame[9:12]
    q = points - p
    a, b, w = q @ r, q @ u, q @ f
    half_w, half_h = frame[12], frame[13]
    X = (a / (w * half_w) + 1.0) * 0.5 * width
    Y = (1.0 - b / (w * half_h)) * 0.5 * height
    return np.stack([X, Y], axis=-1), w


def _segment_distance(c, a, b):
    ab = b - a
    s = np.clip(np.dot(c - a, ab) / max(np.dot(ab, ab), 1e-300), 0.0, 1.0)
    return float(np.linalg.norm(c - (a + s * ab)))


def _edge_distance(h, frame, width, height, cell, centre):
    """Distance in pixels from a pixel centre to the nearest projected edge of a cell's
    triangles (the four sides and the diagonal) and of its vertical edges (the skirts)."""
    if cell[0] < 0:
        return math.inf
    i, j = int(cell[0]), int(cell[1])
    corners = np.array([[i, j, h[j, i]], [i + 1, j, h[j, i + 1]], [i + 1, j + 1, h[j + 1, i + 1]],
                        [i, j + 1, h[j + 1, i]]], dtype=float)
    below = corners.copy()
    below[:, 2] -= 1e4
    xy, w = _project(frame, width, height, np.concatenate([corners, below]))
    if (w <= 0).any():
        return 0.0  # an edge through the camera plane: leave it to the count
    edges = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2), (0, 4), (1, 5), (2, 6), (3, 7)]
    return min(_segment_distance(centre, xy[a], xy[b]) for a, b in edges)


def _mismatches(h, image, ref, frame, width, height):
    """Pixels whose hit cell differs, split into (near an edge, elsewhere)."""
    differs = np.argwhere(np.any(image.cell != ref.cell, axis=-1))
    near, elsewhere = [], []
    for k, c in differs:
        centre = np.array([c + 0.5, k + 0.5])
        d = min(_edge_distance(h, frame, width, height, image.cell[k, c], centre),
                _edge_distance(h, frame, width, height, ref.cell[k, c], centre))
        (near if d <= EDGE_PIXELS else elsewhere).append((int(k), int(c), d))
    return near, elsewhere


def _assert_depths(image, ref, rtol, context):
    same = np.all(image.cell == ref.cell, axis=-1) & np.isfinite(ref.t)
    assert np.array_equal(np.isfinite(image.t[same]), np.isfinite(ref.t[same])), context
    err = np.abs(image.t[same] - ref.t[same]) / ref.t[same]
    assert err.size == 0 or err.max() <= rtol, (
        f"{context}: depth differs by {err.max():.3g} relative at pixel "
        f"{np.argwhere(same)[int(np.argmax(err))].tolist()}")


@pytest.mark.parametrize("algorithm", raster.EXACT_RASTERISERS)
@pytest.mark.parametrize("name,position,look_at", VIEWS, ids=[v[0] for v in VIEWS])
@pytest.mark.parametrize("seed", [1, 2])
def test_exact_pair_agrees_with_tracer(algorithm, name, position, look_at, seed):
    h = random_field(seed)
    width, height = 160, 90
    frame, _, _ = _camera(position, look_at, 60, width, height)
    ref = raster.trace("dda", h, position, look_at, 60, width, height)
    image = raster.render(algorithm, h, position, look_at, 60, width, height)
    context = f"{algorithm}, view {name}, seed {seed}, field {h.shape}"
    near, elsewhere = _mismatches(h, image, ref, frame, width, height)
    assert not elsewhere, f"{context}: cells differ away from any edge at {elsewhere[:5]}"
    # random heights put no pixel centre on an edge: none expected here
    assert len(near) == 0, f"{context}: {len(near)} pixels on edges: {near[:5]}"
    _assert_depths(image, ref, 1e-9, context)
    hit = np.isfinite(ref.t)
    assert np.allclose(image.normal[hit], ref.normal[hit], atol=1e-9), context


@pytest.mark.parametrize("algorithm", raster.EXACT_RASTERISERS)
def test_pixel_centres_on_edges_are_the_only_disagreements(algorithm):
    """A symmetric view of a level plane puts the centre column of pixel centres exactly on
    the grid line x = 16 and the centre row on y = 16 (the rays through the image's
    horizontal midline meet the plane on the line through look_at along `right`). There
    the fill rule and the tracer's half-open cells may pick different neighbours, at the
    same depth. Count them: only those pixels disagree."""
    h = np.zeros((33, 33), dtype=np.float32)
    position, look_at = (16.0, -8.0, 10.0), (16.0, 16.0, 0.0)
    width, height = 81, 61  # odd: the centre column looks along x = 16
    frame, _, _ = _camera(position, look_at, 60, width, height)
    ref = raster.trace("dda", h, position, look_at, 60, width, height)
    image = raster.render(algorithm, h, position, look_at, 60, width, height)
    near, elsewhere = _mismatches(h, image, ref, frame, width, height)
    assert not elsewhere, f"{algorithm}: cells differ away from any edge at {elsewhere[:5]}"
    # every disagreement is on the centre column or row, and the depths still agree
    assert all(c == width // 2 or k == height // 2 for k, c, _ in near), near[:5]
    assert 0 < len(near) <= height + width, len(near)
    hit = np.isfinite(ref.t)
    assert np.allclose(image.t[hit], ref.t[hit], rtol=1e-9, atol=0)


@pytest.mark.parametrize("seed", [0, 3, 7])
def test_watertight_single_sheet(seed):
    """Seen from high above every ray crosses the surface once: exactly one front-facing
    fragment where the tracer hits (no crack, no double hit), none elsewhere."""
    h = random_field(seed, rows=41, cols=37, relief=3.0)
    position = (18.0, 20.0, 2000.0)
    look_at = (18.0, 20.5, 0.0)  # almost straight down; up stays +z
    for width, height in ((97, 83), (256, 256)):
        ref = raster.trace("dda", h, position, look_at, 1.6, width, height)
        image = raster.render("zbuffer", h, position, look_at, 1.6, width, height,
                              coverage=True)
        hit = np.isfinite(ref.t)
        assert hit.any() and not hit.all()  # the field's border is in view
        cover = image.coverage
        assert (cover[hit] == 1).all(), (
            f"seed {seed}, {width}x{height}: coverage {np.unique(cover[hit])} where the "
            f"tracer hits; first bad pixel {np.argwhere(hit & (cover != 1))[:1].tolist()}")
        assert (cover[~hit] == 0).all(), f"seed {seed}: fragments where the tracer misses"


def test_watertight_plane():
    """A plane seen obliquely: one fragment per covered pixel, the same mask as the tracer."""
    h = np.full((20, 30), 1.5, dtype=np.float32)
    position, look_at = (-4.0, -3.0, 9.0), (15.0, 10.0, 1.5)
    ref = raster.trace("dda", h, position, look_at, 70, 200, 120)
    image = raster.render("zbuffer", h, position, look_at, 70, 200, 120, coverage=True)
    hit = np.isfinite(ref.t)
    wall = np.isclose(ref.normal[..., 2], 0.0) & hit  # the skirts: a second sheet
    assert ((image.coverage == 1) == (hit & ~wall) | ((image.coverage == 1) & wall)).all()
    assert (image.coverage[~hit] == 0).all()
    assert np.array_equal(np.isfinite(image.t), hit)


def test_skirts_are_walls():
    """A camera below the field's lowest height, outside it, sees only the side faces."""
    h = random_field(5, rows=20, cols=20, relief=2.0) + np.float32(10.0)
    position, look_at = (-10.0, 9.5, 5.0), (10.0, 9.5, 5.0)
    ref = raster.trace("dda", h, position, look_at, 60, 64, 48)
    image = raster.render("zbuffer", h, position, look_at, 60, 64, 48)
    hit = np.isfinite(ref.t)
    assert hit.any()
    assert np.array_equal(np.isfinite(image.t), hit)
    assert np.array_equal(image.cell, ref.cell)
    assert np.allclose(image.normal[hit], [-1.0, 0.0, 0.0])
    assert np.allclose(image.t[hit], ref.t[hit], rtol=1e-9)


def test_painter_equals_zbuffer_and_stops_when_full():
    h = random_field(11, rows=64, cols=64, relief=6.0)
    position, look_at = (32.0, -20.0, 15.0), (32.0, 40.0, 3.0)
    z = raster.render("zbuffer", h, position, look_at, 50, 120, 60)
    p = raster.render("painter", h, position, look_at, 50, 120, 60)
    assert np.array_equal(z.cell, p.cell) and np.array_equal(z.t, p.t)
    assert p.counts["pixels_written"] == int(np.isfinite(p.t).sum())
    # looking down into the field from inside: the mask fills, the painter stops early
    position, look_at = (32.0, 32.0, 20.0), (32.0, 45.0, 0.0)
    z = raster.render("zbuffer", h, position, look_at, 40, 64, 48)
    p = raster.render("painter", h, position, look_at, 40, 64, 48)
    assert np.isfinite(p.t).all() and p.counts["stopped_full"] == 1
    assert p.counts["cells"] < z.counts["cells"]
    assert np.array_equal(z.cell, p.cell) and np.array_equal(z.t, p.t)


@pytest.mark.parametrize("algorithm", raster.RASTERISERS)
def test_threads_bit_identical(algorithm):
    """Bands of rows (zbuffer, painter) or ranges of columns (floating_horizon) drawn by
    several threads give the whole-image call's image bit for bit."""
    h = random_field(8, rows=48, cols=56, relief=5.0)
    position, look_at = (-6.0, 20.0, 12.0), (40.0, 30.0, 1.0)
    one = raster.render(algorithm, h, position, look_at, 70, 150, 97, coverage=True)
    for threads in (2, 3, 7):
        many = raster.render(algorithm, h, position, look_at, 70, 150, 97, coverage=True,
                             threads=threads)
        assert np.array_equal(one.t, many.t), f"{algorithm}, {threads} threads: t differs"
        assert np.array_equal(one.cell, many.cell), f"{algorithm}, {threads} threads"
        assert np.array_equal(one.normal, many.normal, equal_nan=True)
        if one.coverage is not None:
            assert np.array_equal(one.coverage, many.coverage)


def test_frustum_culling_counts():
    h = random_field(2, rows=65, cols=65)
    image = raster.render("zbuffer", h, (32.0, 32.0, 10.0), (32.0, 60.0, 5.0), 30, 64, 36)
    c = image.counts
    assert c["cells"] == 64 * 64
    assert 0 < c["cells_culled"] < c["cells"]
    assert c["cells_drawn"] == c["cells"] - c["cells_culled"]
    assert c["pixels_written"] >= np.isfinite(image.t).sum()


# ---- floating horizon --------------------------------------------------------------------

def _simple_fields(rows=65, cols=65):
    y, x = np.mgrid[0:rows, 0:cols].astype(float)
    return {
        "plane": (0.05 * x + 0.02 * y).astype(np.float32),
        "ridge": (4.0 * np.exp(-((x - 32) / 6.0) ** 2)).astype(np.float32),
        "spike": np.where((x == 32) & (y == 40), 8.0, 0.0).astype(np.float32),
    }


@pytest.mark.parametrize("name", ["plane", "ridge", "spike"])
@pytest.mark.parametrize("step", [0.5, 0.1])
def test_floating_horizon_within_bound(name, step):
    """Level camera: 0 <= t - t_exact <= step |d| / |d_ground| on every pixel both hit; the
    pixels hit by one only and the cell disagreements shrink with the step."""
    h = _simple_fields()[name]
    position, look_at = (-10.0, 5.0, 6.0), (40.0, 35.0, 6.0)  # level: no pitch
    width, height = 120, 60
    frame, sx, sy = _camera(position, look_at, 60, width, height)
    ref = raster.trace("dda", h, position, look_at, 60, width, height)
    image = raster.render("floating_horizon", h, position, look_at, 60, width, height,
                          step=step)
    f, r, u = frame[3:6], frame[6:9], frame[9:12]
    d = f + sx[None, :, None] * r + sy[:, None, None] * u
    bound = step * np.linalg.norm(d, axis=-1) / np.linalg.norm(d[..., :2], axis=-1)
    both = np.isfinite(image.t) & np.isfinite(ref.t)
    err = image.t[both] - ref.t[both]
    bad = (err < -1e-9 * ref.t[both]) | (err > bound[both] * (1 + 1e-9))
    assert not bad.any(), (f"{name}, step {step}: {bad.sum()} pixels outside the bound, "
                           f"error range [{err.min():.3g}, {err.max():.3g}]")
    stats = raster.diff_images(image, ref)
    # measured: hit by one only <= 5 pixels of 7200 (silhouette rows), cells differ on
    # about 0.25 * step of the pixels (a sample one step behind lands in the next cell)
    assert stats["hit_by_one"] <= 8, stats
    assert stats["cell_differs"] <= 0.3 * step, stats


def test_floating_horizon_pitched_is_measured():
    """With pitch the column's rays fan out: approximate, measured, not bounded."""
    h = random_field(1)
    position, look_at = (-5.0, -6.0, 20.0), (20.0, 16.0, 1.0)
    ref = raster.trace("dda", h, position, look_at, 60, 160, 90)
    image = raster.render("floating_horizon", h, position, look_at, 60, 160, 90, step=0.25)
    stats = raster.diff_images(image, ref)
    assert stats["both_hit"] > 0.9 * np.isfinite(ref.t).sum()
    assert stats["depth_median_abs"] < 1.0, stats


@pytest.mark.parametrize("view", ["level", "above"])
@pytest.mark.parametrize("name", ["plane", "ridge"])
def test_hidden_lines_draw_only_visible_points(name, view):
    """The hidden-line form on a plane and a ridge: every drawn point is visible (its
    depth within 5 % of the exact image's at that pixel; a drawn point sits on its
    column's centre, within a pixel of the row's centre); on the ridge's level view the
    sections behind it are hidden below its silhouette."""
    y, x = np.mgrid[0:33, 0:33].astype(float)
    h = {"plane": 0.05 * x + 0.02 * y,
         "ridge": 4.0 * np.exp(-((y - 16) / 3.0) ** 2)}[name].astype(np.float32)
    position, look_at = {"level": ((16.0, -12.0, 3.0), (16.0, 30.0, 1.0)),
                         "above": ((-8.0, -10.0, 14.0), (16.0, 16.0, 0.0))}[view]
    lines = raster.hidden_lines(h, position, look_at, 60, 200, 120)
    exact = raster.render("zbuffer", h, position, look_at, 60, 200, 120)
    drawn = lines.lines
    assert drawn.sum() > 1000
    # a point on the far edge or a silhouette may sit in a pixel whose centre sees the sky
    assert (drawn & np.isinf(exact.t)).sum() <= 2 * 200
    hidden = drawn & np.isfinite(exact.t) & (lines.t > exact.t * 1.05)
    if name == "ridge" and view == "above":
        # measured: 18 of 4360 points next to the ridge's silhouette, where the pixel
        # centre sees the ground behind while the point lies on the crest
        assert hidden.sum() <= 0.01 * drawn.sum(), hidden.sum()
    else:
        assert not hidden.any(), f"{hidden.sum()} hidden points drawn"
    assert np.isinf(lines.t[~drawn]).all() and (lines.cell[~drawn] == -1).all()
    if name == "ridge" and view == "level":
        assert lines.counts["pixels_written"] < 0.8 * lines.counts["fragments"]


# ---- bad input, empty views, tiny images ----------------------------------------------

@pytest.mark.parametrize("algorithm", raster.RASTERISERS)
def test_one_pixel_image(algorithm):
    h = random_field(4, rows=9, cols=9)
    position, look_at = (-2.0, -2.0, 10.0), (4.0, 4.0, 1.0)
    image = raster.render(algorithm, h, position, look_at, 30, 1, 1)
    ref = raster.trace("dda", h, position, look_at, 30, 1, 1)
    assert image.t.shape == (1, 1) and image.cell.shape == (1, 1, 2)
    if algorithm != "floating_horizon":
        assert np.array_equal(image.cell, ref.cell)
        assert np.allclose(image.t, ref.t, rtol=1e-9)


@pytest.mark.parametrize("algorithm", raster.RASTERISERS)
def test_empty_view(algorithm):
    """Looking away from the field: every pixel misses; everything culled."""
    h = random_field(4, rows=9, cols=9)
    image = raster.render(algorithm, h, (-2.0, -2.0, 10.0), (-20.0, -20.0, 12.0), 60, 16, 9)
    assert np.isinf(image.t).all() and (image.cell == -1).all()
    assert np.isnan(image.normal).all()
    if algorithm == "zbuffer":
        assert image.counts["cells_culled"] == image.counts["cells"]


@pytest.mark.parametrize("kwargs,match", [
    (dict(position=(math.nan, 0.0, 5.0)), "position"),
    (dict(position=(0.0, 0.0)), "position"),
    (dict(look_at=(math.inf, 0.0, 0.0)), "look_at"),
    (dict(look_at=(-2.0, -2.0, 10.0)), "look_at: must differ"),
    (dict(fov=0.0), "fov"),
    (dict(fov=180.0), "fov"),
    (dict(width=0), "width"),
    (dict(height=(1 << 24) + 1), "height"),
    (dict(position=(4.0, 4.0, -1.0), look_at=(8.0, 8.0, 1.0)), "below the surface"),
    (dict(position=(1e300, 0.0, 5.0)), "position"),
    (dict(step=0.0), "step"),
    (dict(algorithm="scanline"), "algorithm"),
    (dict(outputs=("depth",)), "outputs"),
])
@pytest.mark.parametrize("algorithm", raster.RASTERISERS)
def test_bad_cameras_raise(kwargs, match, algorithm):
    h = random_field(4, rows=9, cols=9)
    args = dict(algorithm=algorithm, heights=h, position=(-2.0, -2.0, 10.0),
                look_at=(4.0, 4.0, 1.0), fov=30.0, width=8, height=8)
    args.update(kwargs)
    step = args.pop("step", 0.5)
    outputs = args.pop("outputs", ("t", "cell", "normal"))
    with pytest.raises(ValueError, match=match):
        raster.render(**args, step=step, outputs=outputs)


def test_non_integer_size_raises_type_error():
    h = random_field(4, rows=9, cols=9)
    with pytest.raises(TypeError, match="width"):
        raster.render("zbuffer", h, (-2.0, -2.0, 10.0), (4.0, 4.0, 1.0), 30, 8.5, 8)


def test_heights_not_modified_and_any_layout():
    h = random_field(6, rows=12, cols=10).astype(np.float64)
    before = h.copy()
    a = raster.render("zbuffer", h, (-2.0, -2.0, 10.0), (4.0, 4.0, 1.0), 40, 20, 12)
    b = raster.render("zbuffer", np.asfortranarray(h).astype(">f8"), (-2.0, -2.0, 10.0),
                      (4.0, 4.0, 1.0), 40, 20, 12)
    assert np.array_equal(h, before)
    assert np.array_equal(a.cell, b.cell) and np.array_equal(a.t, b.t)


def test_diff_images():
    h = random_field(1)
    position, look_at = (-5.0, -6.0, 20.0), (20.0, 16.0, 1.0)
    a = raster.render("zbuffer", h, position, look_at, 60, 40, 30)
    same = raster.diff_images(a, a)
    assert same["cell_differs"] == 0 and same["depth_max_abs"] == 0 and same["hit_by_one"] == 0
    b = raster.render("zbuffer", h, position, look_at, 60, 40, 30)
    b.t = b.t.copy()
    b.cell = b.cell.copy()
    k = np.argwhere(np.isfinite(b.t))[0]
    b.t[tuple(k)] += 0.5
    b.cell[k[0], k[1]] = (-1, -1)
    d = raster.diff_images(a, b)
    assert d["cell_differs"] == pytest.approx(1 / a.t.size)
    assert d["depth_max_abs"] == pytest.approx(0.5)
    with pytest.raises(ValueError, match="b: image"):
        raster.diff_images(a, raster.render("zbuffer", h, position, look_at, 60, 20, 30))


@pytest.mark.parametrize("seed", range(40))
def test_fuzz_decoder_runs(seed):
    """The fuzz branch's invariants on seeded random inputs (the fuzzer proper runs it
    under the sanitizers)."""
    rng = np.random.default_rng(seed)
    raster.fuzz_one(rng.bytes(int(rng.integers(0, 120))))


def test_crossover_study_runs(tmp_path):
    """The study's library entry on a tiny tier: every file written, one summary row per
    case with a positive ratio (no timing is asserted)."""
    from bench.studies import raster_vs_trace

    tier = dict(images=[(32, 18)], fields=[64], repeats=1)
    paths = raster_vs_trace.run(str(tmp_path), tier=tier, threads=2, counts=False,
                                echo=lambda *a: None)
    for key in ("csv", "md", "png", "env"):
        assert (tmp_path / paths[key].split("/")[-1]).exists(), key
    table = (tmp_path / "raster_vs_trace.md").read_text()
    assert table.count("| 64^2 |") == 2  # two views
    import csv

    with open(paths["csv"]) as f:
        rows = list(csv.DictReader(f))
    renderers = {r["renderer"] for r in rows}
    assert {"zbuffer", "painter", "floating_horizon", "watkins", "warnock",
            "zbuffer@threads"} <= renderers
    assert all(float(r["ns_per_pixel"]) > 0 for r in rows)
    assert "| watkins ms | warnock ms |" in table
    assert all(float(r["median_ms"]) > 0 for r in rows)


def test_render_command_takes_rasterisers_and_diffs_them(tmp_path):
    """``hftrace render --algorithm zbuffer --diff zbuffer dda`` writes the same channels as
    a tracer, and the exact pair differs on no pixel of a small view."""
    import OpenEXR

    from bench.cli import main

    out = str(tmp_path / "img")
    assert main(["render", "fbm", "--size", "40", "--width", "48", "--height", "27",
                 "--algorithm", "zbuffer", "--diff", "zbuffer", "dda", "--out", out,
                 "--threads", "1"]) == 0
    with OpenEXR.File(out + ".exr") as f:
        assert set(f.channels()) == {"Z", "N.x", "N.y", "N.z", "cellsVisited", "runsVisited"}
    from bench.cli.render import render_files

    paths = render_files("fbm", size=40, algorithm="painter", width=48, height=27,
                         out=str(tmp_path / "p"), diff=("painter", "dda"), threads=1,
                         echo=lambda *_: None)
    assert paths["diff"]["pixels"] == 48 * 27
    assert paths["diff"]["cell_differs"] == 0.0
    assert main(["render", "fbm", "--size", "8", "--algorithm", "zbuffer",
                 "--surface", "bilinear", "--out", out]) == 2


def test_a_field_of_view_too_narrow_to_project_is_refused_not_drawn_wrong():
    """The fuzzer's find: at fov 1e-300 the z-buffer's projection left the floating range
    and drew a farther cell than the exact trace; the rasterisers now refuse it, naming
    fov, and at the narrowest fov they take they still agree with the trace."""
    from algos import raster as R

    heights = np.array([[4.375, 1.25, 0, 0], [0, 0, 0, 0], [14.375, 11.875, 12.75, 6.75],
                        [0, -2.75, -4.5, -2.0]])
    position, look_at = [1e-116, -26.3125, 0.0], [2.0, 1.0, 0.0]
    for algorithm in ("zbuffer", "warnock", "painter"):
        with pytest.raises(ValueError, match="fov: the rasterisers need at least"):
            R.render(algorithm, heights, position, look_at, 1e-300, 7, 17)
    traced = R.trace("dda_maxmip", heights, position, look_at, R.MIN_RASTER_FOV, 7, 17)
    for algorithm in ("zbuffer", "warnock"):
        drawn = R.render(algorithm, heights, position, look_at, R.MIN_RASTER_FOV, 7, 17)
        assert np.array_equal(drawn.cell, traced.cell)
