"""The optional C Embree 3 peer (algos.peers.embree3): the same first hits as our exact
`triangles` kernel to float32 tolerance, on the grid and the triangle geometry, single
rays and every native packet width. Skips where libembree-dev was not there at build time.
"""
import numpy as np
import pytest

import algos
import datasets_gen
from algos.intersect import prepare_timed_intersect
from algos.peers import embree3 as embree3_peer
from algos.render import default_camera
from datasets_gen import rays as raysets
from datasets_gen.rays import first_hit_rays

pytestmark = pytest.mark.skipif(not embree3_peer.available(),
                                reason=f"C Embree 3 peer: {embree3_peer.unavailable_reason()}")

#: Embree computes in float32: |t - t_exact| <= TOLERANCE (1 + t) (as bench-intersect's agree)
TOLERANCE = 1e-4
GEOMETRIES = ("grid", "triangles")


@pytest.fixture(scope="module")
def field():
    return algos.Field(datasets_gen.load("fbm", size=256, seed=1).heights)


def _mismatches(t, exact):
    """(rays whose hit/miss differs, rays both hit whose t differs beyond TOLERANCE)."""
    hit, ref = np.isfinite(t), np.isfinite(exact)
    both = hit & ref
    far = np.abs(t[both] - exact[both]) > TOLERANCE * (1 + np.abs(exact[both]))
    return int((hit != ref).sum()), int(far.sum())


def _widths():
    return embree3_peer.native_widths() if embree3_peer.available() else (1,)


def test_registered_next_to_embree():
    entry = algos.INTERSECTOR_REGISTRY["embree3"]
    assert entry.kind == "peer" and entry.accuracy == "float32-peer"
    assert entry.surfaces == ("triangles",)
    names = list(algos.INTERSECTORS)
    assert names.index("embree3") == names.index("embree") + 1


@pytest.mark.parametrize("packet", _widths())
@pytest.mark.parametrize("geometry", GEOMETRIES)
def test_first_hits_agree_with_the_exact_triangles_kernel(field, geometry, packet):
    # seeded random azimuths at three run lengths, 3000 rays each
    for r in (1, 5, 25):
        o, d = first_hit_rays(field, r, 3000, 11)
        exact = algos.intersect("runs", field, o, d, outputs=("t", "cell", "normal"))
        got = algos.intersect("embree3", field, o, d, outputs=("t", "cell", "normal"), threads=1,
                              geometry=geometry, packet=packet)
        hit_miss, far = _mismatches(got.t, exact.t)
        assert (hit_miss, far) == (0, 0), (
            f"embree3 geometry={geometry} packet={packet} r={r} seed=11 fbm256: {hit_miss} "
            f"hit/miss and {far} t mismatches of {len(o)} rays")
        both = np.isfinite(exact.t)
        assert both.sum() > 1000
        # cells: Embree's float32 hit may land on the neighbour across an edge
        assert (got.cell[both] == exact.cell[both]).all(axis=1).mean() > 0.999
        assert np.allclose(got.normal[both], exact.normal[both], atol=1e-4)


def _wall_hits(field, o, d, t):
    """Rays whose exact hit is where they enter the footprint's box below the surface: the
    conventions' solid has side walls there (a hit at t0), a triangle mesh has none."""
    rows, cols = field.heights.shape
    with np.errstate(divide="ignore", invalid="ignore"):
        entry = np.zeros(len(o))
        for k, top in ((0, cols - 1.0), (1, rows - 1.0)):
            a, b = (0 - o[:, k]) / d[:, k], (top - o[:, k]) / d[:, k]
            entry = np.maximum(entry, np.where(d[:, k] != 0, np.minimum(a, b), 0))
    return np.isfinite(t) & (np.abs(t - entry) <= 1e-9 * (1 + np.abs(t)))


@pytest.mark.parametrize("packet", _widths())
def test_camera_batch_agrees_with_coherent_packets(field, packet):
    position, look_at = default_camera(field.heights)
    rs = raysets.pinhole(position, look_at, 60.0, 96, 54)
    exact = algos.intersect("runs", field, rs.origins, rs.directions)
    walls = _wall_hits(field, rs.origins, rs.directions, exact.t)
    assert 0 < walls.sum() < 0.05 * len(walls)  # the camera sees the near side walls
    for coherent in (False, True):
        got = algos.intersect("embree3", field, rs.origins, rs.directions, threads=1,
                              packet=packet, coherent=coherent)
        assert np.isinf(got.t[walls]).all()
        assert _mismatches(got.t[~walls], exact.t[~walls]) == (0, 0), (packet, coherent)


def test_the_grid_is_laid_out_on_the_conventions_diagonal():
    # one cell, h00 = h11 = 0 and h10 = h01 = 1: at (u, v) = (0.6, 0.2) the conventions'
    # split (u = v) gives s = h00 + (h10 - h00) u + (h11 - h10) v = 0.4; Embree's own grid
    # split (u + v = 1, triangles v0 v1 v3 and v2 v3 v1) gives the plane s = u + v = 0.8
    heights = np.array([[0.0, 1.0], [1.0, 0.0]])
    o, d = np.array([[0.6, 0.2, 2.0]]), np.array([[0.0, 0.0, -1.0]])
    assert algos.intersect("runs", heights, o, d).t[0] == pytest.approx(1.6)
    field = algos.Field(heights)
    mirrored = algos.intersect("embree3", field, o, d, geometry="grid").t[0]
    triangles = algos.intersect("embree3", field, o, d, geometry="triangles").t[0]
    native = algos.intersect("embree3", field, o, d, geometry="grid_native").t[0]
    assert mirrored == pytest.approx(1.6, abs=1e-6) and triangles == pytest.approx(1.6, abs=1e-6)
    assert native == pytest.approx(1.2, abs=1e-6)


def test_timed_run_gives_the_hits(field):
    o, d = first_hit_rays(field, 5, 2000, 12)
    exact = algos.intersect("runs", field, o, d).t
    for packet in _widths():
        run, t = prepare_timed_intersect("embree3", field, o, d, packet=packet, coherent=True)
        assert run() > 0
        assert _mismatches(t(), exact) == (0, 0), packet


def test_build_stats_record_embree_bytes(field):
    embree3_peer.embree3_scene(field, "grid")
    embree3_peer.embree3_scene(field, "triangles")
    grid, tri = field.build_stats["embree3-grid"], field.build_stats["embree3-triangles"]
    assert grid["bytes"] > field.cell_heights.size * 12  # at least the float3 vertices
    assert tri["bytes"] > grid["bytes"] and grid["seconds"] >= 0


def test_threads_give_the_same_hits(field):
    o, d = first_hit_rays(field, 5, 3000, 13)
    one = algos.intersect("embree3", field, o, d, threads=1)
    two = algos.intersect("embree3", field, o, d, threads=2)
    assert np.array_equal(one.t, two.t) and np.array_equal(one.cell, two.cell)


def test_tmin_and_tmax(field):
    o, d = first_hit_rays(field, 5, 500, 14)
    exact = algos.intersect("runs", field, o, d, tmin=5.0, tmax=60.0).t
    got = algos.intersect("embree3", field, o, d, tmin=5.0, tmax=60.0).t
    assert _mismatches(got, exact) == (0, 0)


@pytest.mark.parametrize("options, argument", [
    (dict(packet=3), "packet"), (dict(packet=True), "packet"), (dict(geometry="quads"), "geometry"),
    (dict(coherent=1), "coherent"), (dict(robust=True), "robust")])
def test_bad_options_name_the_argument(field, options, argument):
    o, d = np.array([[1.5, 1.5, 300.0]]), np.array([[0.0, 0.0, -1.0]])
    with pytest.raises((ValueError, TypeError), match=argument):
        algos.intersect("embree3", field, o, d, **options)


def test_packet_width_the_cpu_lacks_is_refused(field):
    missing = [w for w in embree3_peer.PACKET_WIDTHS if w not in embree3_peer.native_widths()]
    if not missing:
        pytest.skip("this CPU runs every packet width natively")
    o, d = np.array([[1.5, 1.5, 300.0]]), np.array([[0.0, 0.0, -1.0]])
    with pytest.raises(ValueError, match=f"packet: this CPU does not run {missing[0]}-wide"):
        algos.intersect("embree3", field, o, d, packet=missing[0])


def test_grid_side_limit():
    with pytest.raises(ValueError, match="heights: Embree's grid geometry takes at most 32767"):
        embree3_peer.Embree3Scene(np.zeros((2, 32768)), "grid")


def test_peers_refuse_stats(field):
    """A BVH visits no cells: zeros in ``stats`` would read as a kernel that does no work
    (a trial found them). Refused by name, for both peers; render's count images stay zero."""
    o = np.array([[3.5, 3.5, 50.0]])
    d = np.array([[0.3, 0.2, -1.0]])
    for name in ("embree", "embree3"):
        with pytest.raises(ValueError, match=f"outputs: {name} .*no per-ray statistics"):
            algos.intersect(name, field, o, d, outputs=("t", "stats"))
    assert np.isfinite(algos.intersect("embree3", field, o, d).t[0])
    image = algos.render(field, "embree3", width=4, height=3)
    assert not image.cells_visited.any()
