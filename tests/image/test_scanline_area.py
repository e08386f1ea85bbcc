"""Watkins' scanline and Warnock's area-subdivision renderers (cext/raster/watkins.c,
cext/raster/warnock.c) against the zbuffer and the exact tracer ``dda``.

Both decide the same pixel centres by the zbuffer's top-left rule and break exact depth
ties in its drawing order, so the rule is the raster tests': the same hit cell on every
pixel except where the pixel centre lies within rounding of a projected edge (the zbuffer
tracks its edges incrementally, these two evaluate them directly), and the same depth to
rounding. Views: the raster tests' fixed views, seeded random cameras (inside and outside
the field, steep and grazing, narrow and wide), and the plane, ridge and spike fields.
"""
from __future__ import annotations

import numpy as np
import pytest

from algos import raster
from tests.image.test_raster import VIEWS, _camera, _mismatches, _simple_fields, random_field

RENDERERS = ("watkins", "warnock")


def _assert_same_image(h, image, ref, position, look_at, fov, width, height, context,
                       max_near=0):
    """Cells equal except within rounding of a projected edge (at most ``max_near`` such
    pixels); depths equal to 1e-9 relative where the cells agree; normals to 1e-9."""
    frame, _, _ = _camera(position, look_at, fov, width, height)
    near, elsewhere = _mismatches(h, image, ref, frame, width, height)
    assert not elsewhere, (f"{context}: cells differ away from any edge at {elsewhere[:5]} "
                           f"(camera {position} -> {look_at}, fov {fov}, {width}x{height})")
    assert len(near) <= max_near, f"{context}: {len(near)} pixels on edges: {near[:5]}"
    same = np.all(image.cell == ref.cell, axis=-1)
    assert np.array_equal(np.isfinite(image.t[same]), np.isfinite(ref.t[same])), context
    hit = same & np.isfinite(ref.t)
    # A skirt is a pair of triangles reaching about 1e6 field sides below the field, so 1/w
    # interpolated across it is exact to about 1e-9 only (the zbuffer's as well)
    wall = hit & (ref.normal[..., 2] == 0)
    err = np.abs(image.t[hit] - ref.t[hit]) / ref.t[hit]
    rtol = np.where(wall[hit], 1e-7, 1e-9)
    assert err.size == 0 or (err <= rtol).all(), (
        f"{context}: depth differs by {np.max(err / rtol) :.3g} x the tolerance")
    assert np.allclose(image.normal[hit], ref.normal[hit], atol=1e-9), context


@pytest.mark.parametrize("algorithm", RENDERERS)
@pytest.mark.parametrize("name,position,look_at", VIEWS, ids=[v[0] for v in VIEWS])
@pytest.mark.parametrize("seed", [1, 2])
def test_fixed_views_equal_zbuffer_and_dda(algorithm, name, position, look_at, seed):
    h = random_field(seed)
    width, height = 160, 90
    image = raster.render(algorithm, h, position, look_at, 60, width, height)
    for reference in ("zbuffer", "dda"):
        ref = (raster.render(reference, h, position, look_at, 60, width, height)
               if reference == "zbuffer" else raster.trace("dda", h, position, look_at, 60,
                                                           width, height))
        _assert_same_image(h, image, ref, position, look_at, 60, width, height,
                           f"{algorithm} vs {reference}, view {name}, seed {seed}")


def _random_camera(rng, h):
    """A camera inside or outside the field, high above it or just above its surface
    (near cells then cross the near plane), looking at a point of the footprint; a random
    field of view and image size."""
    rows, cols = h.shape
    hmin, hmax = float(h.min()), float(h.max())
    x, y = rng.uniform(-0.5, 1.5) * cols, rng.uniform(-0.5, 1.5) * rows
    if rng.random() < 0.5:
        z = hmax + 10 ** rng.uniform(-1, 1.7)
    else:
        z = rng.uniform(hmin, hmax + 1.0)
        if 0 <= x <= cols - 1 and 0 <= y <= rows - 1:
            z = max(z, raster._surface_at(h, x, y) + 10 ** rng.uniform(-3, 0))
    look_at = np.array([rng.uniform(0, cols - 1), rng.uniform(0, rows - 1),
                        rng.uniform(hmin - 2.0, hmax)])
    fov = float(rng.uniform(15, 110))
    width, height = int(rng.integers(1, 90)), int(rng.integers(1, 70))
    return (x, y, z), tuple(look_at), fov, width, height


@pytest.mark.parametrize("seed", range(40))
def test_random_cameras_equal_zbuffer_and_dda(seed):
    rng = np.random.default_rng(1000 + seed)
    rows, cols = int(rng.integers(2, 40)), int(rng.integers(2, 40))
    h = (rng.random((rows, cols)) * rng.uniform(0.1, 8.0)).astype(np.float32)
    position, look_at, fov, width, height = _random_camera(rng, h)
    ref = raster.trace("dda", h, position, look_at, fov, width, height)
    zbuffer = raster.render("zbuffer", h, position, look_at, fov, width, height)
    for algorithm in RENDERERS:
        image = raster.render(algorithm, h, position, look_at, fov, width, height)
        context = f"{algorithm}, seed {seed}, field {h.shape}"
        _assert_same_image(h, image, zbuffer, position, look_at, fov, width, height,
                           context + " vs zbuffer")
        _assert_same_image(h, image, ref, position, look_at, fov, width, height,
                           context + " vs dda")


# (name, position, look_at): the floating-horizon tests' level view, a view from above the
# south-west corner, and one from inside looking across the ridge and at the spike
SIMPLE_VIEWS = [
    ("level", (-10.0, 5.0, 6.0), (40.0, 35.0, 6.0)),
    ("above", (-8.0, -10.0, 30.0), (32.0, 32.0, 0.0)),
    ("across", (10.0, 50.0, 3.0), (50.0, 40.0, 1.0)),
]


@pytest.mark.parametrize("algorithm", RENDERERS)
@pytest.mark.parametrize("field", ["plane", "ridge", "spike"])
@pytest.mark.parametrize("view,position,look_at", SIMPLE_VIEWS, ids=[v[0] for v in SIMPLE_VIEWS])
def test_plane_ridge_spike(algorithm, field, view, position, look_at):
    h = _simple_fields()[field]
    width, height = 120, 60
    image = raster.render(algorithm, h, position, look_at, 60, width, height)
    zbuffer = raster.render("zbuffer", h, position, look_at, 60, width, height)
    ref = raster.trace("dda", h, position, look_at, 60, width, height)
    context = f"{algorithm}, {field}, view {view}"
    # the spike's four faces meet the flat ground along grid lines, where a pixel centre
    # can fall exactly on an edge; the plane and ridge have none in these views
    _assert_same_image(h, image, zbuffer, position, look_at, 60, width, height,
                       context + " vs zbuffer", max_near=4)
    _assert_same_image(h, image, ref, position, look_at, 60, width, height,
                       context + " vs dda", max_near=4)


@pytest.mark.parametrize("seed", [0, 3])
def test_one_sheet_from_above_hits_where_the_tracer_hits(seed):
    """Seen from high above (one sheet of surface in view, the field's border in view), both
    cover exactly the tracer's pixels: no crack, no pixel outside the field drawn."""
    h = random_field(seed, rows=41, cols=37, relief=3.0)
    position, look_at = (18.0, 20.0, 2000.0), (18.0, 20.5, 0.0)
    ref = raster.trace("dda", h, position, look_at, 1.6, 97, 83)
    hit = np.isfinite(ref.t)
    assert hit.any() and not hit.all()
    for algorithm in RENDERERS:
        image = raster.render(algorithm, h, position, look_at, 1.6, 97, 83)
        assert np.array_equal(np.isfinite(image.t), hit), algorithm
        assert np.array_equal(image.cell, ref.cell), algorithm


def test_cost_counts():
    """Watkins decides depth once per span, so fewer spans than pixels; Warnock drops hidden
    and out-of-region tiles (a view from inside the field, where near cells hide most)."""
    h = random_field(11, rows=64, cols=64, relief=6.0)
    position, look_at = (32.0, 10.0, 9.0), (32.0, 50.0, 2.0)
    watkins = raster.render("watkins", h, position, look_at, 50, 120, 60)
    warnock = raster.render("warnock", h, position, look_at, 50, 120, 60)
    hit = int(np.isfinite(watkins.t).sum())
    c = watkins.counts
    assert c["pixels_written"] == hit
    assert 0 < c["samples"] < hit  # spans
    assert c["cells_drawn"] + c["cells_culled"] == c["cells"] == 63 * 63
    c = warnock.counts
    assert c["cells_culled"] > 0 and c["samples"] > 1  # tiles dropped, regions split
    assert c["pixels_written"] >= hit


def test_field_behind_the_camera_is_empty():
    """Every tile behind the near plane: nothing drawn, every pixel a miss."""
    h = random_field(4, rows=9, cols=9)
    for algorithm in RENDERERS:
        image = raster.render(algorithm, h, (-2.0, -2.0, 10.0), (-20.0, -20.0, 10.0), 60, 16, 9)
        assert np.isinf(image.t).all() and (image.cell == -1).all(), algorithm
        assert image.counts["pixels_written"] == 0, algorithm


@pytest.mark.parametrize("algorithm", RENDERERS)
def test_render_command_writes_the_same_files(tmp_path, algorithm):
    """``hftrace render --algorithm watkins|warnock`` writes the EXR and PNG the other
    renderers write, and its image differs from ``dda``'s on no pixel of a small view."""
    import OpenEXR

    from bench.cli.render import render_files

    out = str(tmp_path / algorithm)
    paths = render_files("fbm", size=40, algorithm=algorithm, width=48, height=27, out=out,
                         diff=(algorithm, "dda"), threads=1, echo=lambda *_: None)
    with OpenEXR.File(out + ".exr") as f:
        assert set(f.channels()) == {"Z", "N.x", "N.y", "N.z", "cellsVisited", "runsVisited"}
    assert (tmp_path / f"{algorithm}.png").exists()
    assert paths["diff"]["pixels"] == 48 * 27
    assert paths["diff"]["cell_differs"] == 0.0
