"""The pinhole camera's one home (algos/camera.py): the ray sets, algos.render and the
rasterisers see the same pixels, and every viewing direction renders, a straight-down
(nadir) view included, checked against the brute force and ``dda``."""
from __future__ import annotations

import numpy as np
import pytest

import algos
from algos import camera, raster
from algos.brute import brute_force_hits
from datasets_gen import rays as raysets
from tests.image.test_raster import _camera, _mismatches, random_field


def test_ray_set_and_rasterisers_share_the_frame():
    """datasets_gen.rays.pinhole gives the unit directions of camera.primary_directions,
    bit for bit, and raster.pinhole_frame is camera.pinhole_frame."""
    position, look_at = (-5.0, -6.0, 20.0), (20.0, 16.0, 1.0)
    rs = raysets.pinhole(position, look_at, 60.0, 33, 17)
    frame, sx, sy = camera.pinhole_frame(position, look_at, 60.0, 33, 17)
    assert np.array_equal(rs.directions, camera.primary_directions(frame, sx, sy))
    assert np.array_equal(rs.origins, np.tile(frame[:3], (33 * 17, 1)))
    assert raster.pinhole_frame is camera.pinhole_frame


def test_nadir_frame_has_north_at_the_top():
    """Straight down: right is -x and the image's top looks towards -y (north), the limit
    of a camera heading north as it tilts down; the frame is orthonormal."""
    frame, _, _ = camera.pinhole_frame((5.0, 5.0, 50.0), (5.0, 5.0, 0.0), 40.0, 8, 6)
    forward, right, up = frame[3:6], frame[6:9], frame[9:12]
    assert np.allclose(forward, [0, 0, -1]) and np.allclose(right, [-1, 0, 0])
    assert np.allclose(up, [0, -1, 0])
    # continuity: a camera heading north, pitched down by almost 90 degrees
    tilt, _, _ = camera.pinhole_frame((5.0, 5.0, 50.0), (5.0, 5.0 - 1e-6, 0.0), 40.0, 8, 6)
    assert np.allclose(tilt[6:12], frame[6:12], atol=1e-6)
    zenith, _, _ = camera.pinhole_frame((5.0, 5.0, 0.0), (5.0, 5.0, 9.0), 40.0, 8, 6)
    assert np.allclose(zenith[6:9], [-1, 0, 0]) and np.allclose(zenith[9:12], [0, 1, 0])


def test_custom_up_parallel_to_the_view_is_refused_with_the_range():
    with pytest.raises(ValueError, match="up: .* parallel to the viewing direction"):
        camera.pinhole_frame((0.0, 0.0, 5.0), (3.0, 0.0, 5.0), 60.0, 4, 4, up=(1.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="up: .* parallel"):
        raysets.pinhole((0.0, 0.0, 5.0), (3.0, 0.0, 5.0), 60.0, 4, 4, up=(1.0, 0.0, 0.0))


@pytest.mark.parametrize("seed", [0, 5])
@pytest.mark.parametrize("position", [(18.0, 20.0, 60.0), (-5.0, 30.0, 40.0)],
                         ids=["above", "outside"])
def test_nadir_renders_equal_brute_force_and_dda(seed, position):
    """``algos.render`` with a straight-down camera (refused before) equals the brute force
    pixel for pixel; every exact rasteriser equals ``dda`` except on pixel centres within
    rounding of a projected edge (seen from outside the field, the skirts' vertical edges
    radiate from the image centre)."""
    h = random_field(seed, rows=41, cols=37, relief=3.0)
    look_at = (position[0], position[1], 0.0)
    width, height = 40, 30
    image = algos.render(h, "dda", position=position, look_at=look_at, width=width,
                         height=height, threads=1)
    frame, sx, sy = camera.pinhole_frame(position, look_at, 60.0, width, height)
    d = camera.primary_directions(frame, sx, sy)
    brute_t, brute_cell = brute_force_hits(h, np.broadcast_to(frame[:3], d.shape), d)
    assert np.array_equal(np.isfinite(image.depth).ravel(), np.isfinite(brute_t))
    hit = np.isfinite(brute_t)
    assert hit.sum() > 100
    assert np.allclose(image.depth.ravel()[hit], brute_t[hit], rtol=1e-9)
    # the cells agree, except where the brute force's border rule picks the neighbour a ray
    # only touches along an edge (docs/CONVENTIONS.md, "Points on a cell border"): there
    # the depth is the same
    differs = np.any(image.cell.reshape(-1, 2) != brute_cell, axis=-1) & hit
    assert differs.sum() <= 0.05 * hit.sum(), differs.sum()
    ref = raster.trace("dda", h, position, look_at, 60.0, width, height)
    frame, _, _ = _camera(position, look_at, 60.0, width, height)
    for algorithm in raster.EXACT_RASTERISERS:
        drawn = raster.render(algorithm, h, position, look_at, 60.0, width, height)
        near, elsewhere = _mismatches(h, drawn, ref, frame, width, height)
        assert not elsewhere, f"{algorithm}: cells differ away from any edge at {elsewhere[:5]}"
        assert len(near) <= 0.02 * width * height, (algorithm, len(near))
        same = np.all(drawn.cell == ref.cell, axis=-1) & np.isfinite(ref.t)
        assert np.allclose(drawn.t[same], ref.t[same], rtol=1e-7), algorithm


def test_nadir_through_the_render_command(tmp_path):
    """``hftrace render`` with a camera straight above the field writes its image."""
    from bench.cli import main

    out = str(tmp_path / "nadir")
    assert main(["render", "fbm", "--size", "24", "--width", "20", "--height", "16",
                 "--algorithm", "warnock", "--camera", "12,12,80",
                 "--look-at", "12,12,0", "--out", out, "--threads", "1"]) == 0
    assert (tmp_path / "nadir.exr").exists() and (tmp_path / "nadir.png").exists()


def test_floating_horizon_refuses_views_holding_the_vertical_with_the_range():
    """The floating horizon marches each column over the ground: a nadir view, or any view
    whose vertical field of view holds the straight-down direction, is refused with the
    range that works; a view just inside that range renders."""
    h = random_field(3, rows=33, cols=33, relief=3.0)
    with pytest.raises(ValueError, match="pitch.*below 90 degrees"):
        raster.render("floating_horizon", h, (16.0, 16.0, 40.0), (16.0, 16.0, 0.0), 60, 16, 12)
    # 60 degrees of pitch, 64x48 at fov 60 (half the vertical field 23.4 degrees): renders
    position = np.array([16.0, -10.0, 30.0])
    down = np.array([0.0, np.cos(np.radians(60)), -np.sin(np.radians(60))])
    image = raster.render("floating_horizon", h, position, position + 30 * down, 60, 64, 48)
    assert np.isfinite(image.t).any()
    steeper = np.array([0.0, np.cos(np.radians(70)), -np.sin(np.radians(70))])
    with pytest.raises(ValueError, match="70 \\+ 23.4"):
        raster.render("floating_horizon", h, position, position + 30 * steeper, 60, 64, 48)
