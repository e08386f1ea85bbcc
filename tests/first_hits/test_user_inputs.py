"""Inputs a GIS or NumPy user passes in good faith: masked arrays, float64 heights beyond
float32, directions of any magnitude, cameras given loosely. Each either works exactly
(the brute force agrees) or is refused naming the argument and the value."""
import warnings

import numpy as np
import pytest

import algos
from algos.registry import INTERSECTOR_REGISTRY
from algos.render import PROJECTIONS

STRICT = [n for n, a in INTERSECTOR_REGISTRY.items()
          if a.accuracy in ("exact", "float64") and a.kind != "peer"]


def _rays(seed, n=120, size=17):
    """Rays from around and above a size x size field, mostly downwards."""
    rng = np.random.Generator(np.random.PCG64(seed))
    o = np.column_stack([rng.uniform(-2, size + 1, n), rng.uniform(-2, size + 1, n),
                         rng.uniform(1, 8, n)])
    d = rng.normal(size=(n, 3))
    d[:, 2] -= 0.4
    return o, d


# ---- masked arrays: the mask is the void mask ---------------------------------------------
def _masked_field():
    """A flat field whose sample (row 4, col 6) is a -9999 sentinel under a mask, as
    ``rasterio``'s ``read(masked=True)`` returns a DEM's nodata."""
    h = np.zeros((9, 9))
    h[4, 6] = -9999.0
    return np.ma.masked_equal(h, -9999.0)


def test_masked_array_mask_is_the_void_mask():
    masked = _masked_field()
    field = algos.HeightField(masked)
    assert field.nodata_mask is not None
    np.testing.assert_array_equal(field.nodata_mask, np.ma.getmaskarray(masked))
    # NaN outside the mask is a void too
    both = masked.copy()
    both[1, 1] = np.nan
    assert algos.HeightField(both).nodata_mask[1, 1]
    # a mask with nothing masked is no void
    assert algos.HeightField(np.ma.masked_array(np.zeros((3, 3)))).nodata_mask is None


def test_first_hits_and_renders_refuse_a_masked_sample():
    o, d = np.array([[6.5, 4.5, 5.0]]), np.array([[0.0, 0.0, -1.0]])
    with pytest.raises(ValueError, match=r"heights: sample \(row 4, col 6\) is a void "
                                         r"\(nodata; stored value -9999.0\)"):
        algos.intersect("dda_maxmip", _masked_field(), o, d)
    with pytest.raises(ValueError, match=r"sample \(row 4, col 6\)"):
        algos.render(_masked_field(), "dda", width=4, height=2)


def test_terrain_products_take_the_mask_as_voids():
    masked = _masked_field()
    nan_void = np.where(np.ma.getmaskarray(masked), np.nan, masked.data)
    got = algos.sky_view_factor(masked, 8)
    expected = algos.sky_view_factor(nan_void, 8)
    np.testing.assert_array_equal(got, expected)
    assert np.isnan(got[4, 6])


# ---- heights beyond float32 ---------------------------------------------------------------
def test_float64_heights_beyond_float32_are_refused_with_the_sample():
    h = np.zeros((5, 6))
    h[2, 3] = 1e39  # finite in float64, inf once stored as float32
    with pytest.raises(ValueError, match=r"heights: sample \(row 2, col 3\) = 1e\+39 .*float32"):
        algos.HeightField(h)
    with pytest.raises(ValueError, match=r"heights: sample \(row 2, col 3\) = 1e\+39"):
        algos.intersect("dda", h, [[1.0, 1.0, 5.0]], [[0.0, 0.0, -1.0]])
    h[2, 3] = -3.4e38  # within float32: kept
    assert algos.HeightField(h).nodata_mask is None


# ---- directions of any magnitude ----------------------------------------------------------
@pytest.mark.parametrize("exponent", [32, 40, 200, -200])
@pytest.mark.parametrize("surface", algos.SURFACES)
def test_hits_do_not_depend_on_the_scale_of_the_direction(exponent, surface):
    """``t`` is in units of ``d``: scaling ``d`` by 2^k (exact in binary) scales ``t`` by
    2^-k and changes no hit cell, on every surface (bilinear's root solver once took an
    absolute slack, so at |d| >= 2^32 it accepted roots beyond the cell)."""
    rng = np.random.Generator(np.random.PCG64(7))
    heights = rng.random((17, 17)) * 4
    o, d = _rays(7)
    scale = 2.0 ** exponent
    ref = algos.intersect("dda", heights, o, d, surface=surface)
    for name in STRICT:
        if surface not in INTERSECTOR_REGISTRY[name].surfaces:
            continue
        got = algos.intersect(name, heights, o, d * scale, surface=surface)
        wrong = np.nonzero((got.cell != ref.cell).any(axis=1))[0]
        assert len(wrong) == 0, (
            f"{name} on {surface}, d scaled by 2**{exponent}: {len(wrong)} rays change cell; "
            f"first: origin={o[wrong[0]].tolist()!r} direction={(d[wrong[0]] * scale).tolist()!r} "
            f"cell {got.cell[wrong[0]].tolist()} instead of {ref.cell[wrong[0]].tolist()}")
        np.testing.assert_allclose(got.t * scale, ref.t, rtol=1e-9, err_msg=name)


@pytest.mark.parametrize("scale", [1e-320, 2.0 ** -600, 2.0 ** 600])
def test_directions_beyond_the_documented_magnitudes_are_refused(scale):
    """|d| so small that t overflows (a hit read as a miss) or so large or small that the
    surface's quadratic under- or overflows is refused, naming the ray."""
    o = np.array([[1.5, 2.5, 20.0], [1.5, 2.5, 20.0]])
    d = np.array([[1.0, 1.0, -1.0], [1.0, 1.0, -1.0]])
    d[1] *= scale
    with pytest.raises(ValueError, match=r"directions: ray 1 has a largest component "):
        algos.intersect("dda", np.zeros((33, 33)), o, d)


def test_an_origin_beyond_the_limit_is_refused_with_the_way_round_it():
    """|origins| > 2**30 is refused naming the ray, the component and the remedy (as
    traverse's message does); the remedy, taken, gives the hit at t - s."""
    d = np.array([[1.0, 0.0, -1.0]])
    s = 2.0 ** 31
    far = np.array([[0.5 - s, 16.5, 10.0 + s]])
    with pytest.raises(ValueError, match=r"origins: ray 0 has \|origins\[0, 0\]\| = .* > 2\*\*30, "
                                         r"the documented limit \(start the ray nearer the grid, "
                                         r"at o \+ s d, and add s to its t\)"):
        algos.intersect("dda", np.zeros((33, 33)), far, d)
    near = far + s * d
    assert near.tolist() == [[0.5, 16.5, 10.0]]  # exact in float64
    hit = algos.intersect("dda", np.zeros((33, 33)), near, d)
    assert hit.t[0] == 10.0 and hit.cell[0].tolist() == [10, 16]  # the far ray's t is 10 + s


# ---- other arguments ----------------------------------------------------------------------
def test_outputs_none_is_named():
    with pytest.raises(TypeError, match="outputs: expected"):
        algos.intersect("dda", np.zeros((4, 4)), [[1.0, 1.0, 5.0]], [[0.0, 0.0, -1.0]],
                        outputs=None)


# ---- render: every camera checks its arguments alike ---------------------------------------
HEIGHTS = np.random.Generator(np.random.PCG64(1)).random((33, 33)) * 5
VIEW = dict(position=[16.0, -10.0, 12.0], look_at=[16.0, 16.0, 2.0])


@pytest.mark.parametrize("projection", PROJECTIONS)
@pytest.mark.parametrize("size,error,message", [
    (2.7, TypeError, r"width: expected an integer, got 2.7"),
    ("8", TypeError, r"width: expected an integer, got '8'"),
    (True, TypeError, r"width: expected an integer, got True"),
    (0, ValueError, r"width: expected a size in \[1, 2\^24\], got 0"),
    (2**25, ValueError, r"width: expected a size in \[1, 2\^24\], got 33554432")])
def test_render_sizes_are_checked_on_every_camera(projection, size, error, message):
    with pytest.raises(error, match=message):
        algos.render(HEIGHTS, "dda_maxmip", projection=projection, width=size, height=2, **VIEW)


@pytest.mark.parametrize("projection", PROJECTIONS)
def test_render_names_the_camera_argument(projection):
    def call(**kw):
        args = dict(VIEW, width=4, height=2, projection=projection)
        args.update(kw)
        return algos.render(HEIGHTS, "dda_maxmip", **args)

    with pytest.raises(ValueError, match=r"position: expected a 3-vector .*'abc'"):
        call(position="abc")
    with pytest.raises(ValueError, match=r"look_at: expected a 3-vector .*\[1.0, 2.0\]"):
        call(look_at=[1.0, 2.0])
    with pytest.raises(ValueError, match=r"position: expected a 3-vector .*nan"):
        call(position=[np.nan, 0.0, 5.0])
    with pytest.raises(ValueError, match=r"fov: expected degrees in \(0, 180\), got 'wide'"):
        call(fov="wide")
    # within the camera's coordinates but beyond the tracers' origin limit: named position
    with pytest.raises(ValueError, match=r"position: \[100000000000.0, 0.0, 5.0\] lies beyond 2\*\*30"):
        call(position=[1e11, 0.0, 5.0])
    for fog in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match=r"fog: expected a density >= 0"):
            call(fog=fog)
    assert call(fov="60").depth.shape == (2, 4)  # a number as text, as float() reads it


def test_orthographic_film_beyond_the_origin_limit_names_fov():
    """The orthographic film spans 2 |look_at - position| tan(fov/2): near 180 degrees its
    corners leave the tracers' coordinate range; the error names fov, not origins."""
    with pytest.raises(ValueError, match=r"fov: the orthographic film .* 2\*\*30"):
        algos.render(HEIGHTS, "dda_maxmip", projection="orthographic", width=4, height=2,
                     fov=179.9999999, **VIEW)


# ---- float traversals outside their number range --------------------------------------------
FLOAT_WALKS = [t.name for t in algos.registry.TRAVERSAL_REGISTRY.values()
               if t.precision in ("float64", "float32") and t.plugin is None]


@pytest.mark.parametrize("name", FLOAT_WALKS)
@pytest.mark.parametrize("scale", [1e-320, 1e-50, 1e50])
def test_float_walks_refuse_directions_outside_their_number_range(name, scale):
    """d = (2, 3) x 1e-320 made the float64 walks stop after one cell (1/d overflows);
    dda_f32's float32 copy of d read 1e-50 as zero (one cell) and 1e50 as inf (no cell).
    A float walk refuses such a ray by name; the exact walks take it (the lattice
    rescales d) and equal the reference."""
    precision = algos.registry.TRAVERSAL_REGISTRY[name].precision
    o = np.array([[0.5, 0.25], [0.5, 0.25]])
    d = np.array([[2.0, 3.0], [2.0 * scale, 3.0 * scale]])
    low, high = (2.0**-100, 2.0**100) if precision == "float32" else (2.0**-1000, 2.0**1000)
    if low <= 3.0 * scale <= high:
        expected = [tuple(c) for c in algos.reference_cells(o[0], d[0], (8, 8))]
        assert [tuple(c) for c in algos.traverse(name, o, d, (8, 8))[1].tolist()][:3] == \
            expected[:3]
        return
    with pytest.raises(ValueError, match=rf"directions: ray 1 .* {name} walks in {precision}"):
        algos.traverse(name, o, d, (8, 8))


@pytest.mark.parametrize("name", [t for t in algos.TRAVERSALS
                                  if algos.registry.TRAVERSAL_REGISTRY[t].exact])
def test_exact_walks_take_any_direction_magnitude(name):
    o = np.array([[0.5, 0.25]])
    for scale in (1e-320, 1e-50, 1e50):
        d = np.array([[2.0, 3.0]]) * scale
        (ro,), (rd,) = algos.quantize(o, d)
        expected = [tuple(c) for c in algos.reference_cells(ro, rd, (8, 8))]
        assert [tuple(c) for c in algos.traverse(name, o, d, (8, 8))[0].tolist()] == expected


# ---- masked rays and ranges: refused, not read through their mask --------------------------
@pytest.mark.parametrize("where", ["origins", "directions", "tmin"])
def test_a_masked_ray_entry_is_refused_naming_it(where):
    """A masked ray array's mask was ignored: the masked value underneath was traced."""
    o = np.ma.array([[0.5, 0.5, 3.0], [1.5, 1.5, 3.0]])
    d = np.ma.array([[1.0, 1.0, -1.0], [1.0, 0.5, -1.0]])
    lo = np.ma.array([0.0, 0.0])
    {"origins": o, "directions": d, "tmin": lo}[where][1] = np.ma.masked
    with pytest.raises(ValueError, match=rf"{where}: {where}\[1(, 0)?\] is masked"):
        algos.intersect("dda", np.zeros((5, 5)), o, d, tmin=lo)
    if where != "tmin":
        with pytest.raises(ValueError, match=rf"{where}: {where}\[1, 0\] is masked"):
            algos.traverse("dda", o[:, :2], d[:, :2], (4, 4))


def test_a_masked_array_without_masked_entries_is_read():
    o = np.ma.array([[0.5, 0.5, 3.0]], mask=False)
    got = algos.intersect("dda", np.zeros((5, 5)), o, [[1.0, 1.0, -1.0]])
    assert got.t[0] == 3.0


def test_heights_beyond_float32_raise_without_a_numpy_warning():
    H = np.zeros((5, 5))
    H[2, 2] = 1e39
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=r"heights: sample \(row 2, col 2\) = 1e\+39"):
            algos.intersect("dda", H, [[0.5, 0.5, 3.0]], [[1.0, 1.0, -1.0]])


def test_dda_f32_reads_the_side_of_a_component_float32_rounds_to_minus_zero():
    """dx = -1e-300 is -0.0 in float32: the walk started in column 2 while the float64
    cell tests put the ray's points in column 1, and nothing was tested (a miss)."""
    H = np.full((5, 5), 1.0)
    want_t, want_cell = algos.brute_force_hits(H, [[2, 0, 3]], [[-1e-300, 1, -1]])
    for name in ("dda", "dda_f32"):
        got = algos.intersect(name, H, [[2, 0, 3]], [[-1e-300, 1, -1]])
        assert got.t[0] == want_t[0] == 2.0 and tuple(got.cell[0]) == tuple(want_cell[0])


def test_a_wall_entered_through_a_vertex_faces_along_x_for_every_kernel():
    """At a vertex both faces start the cell; the run walks gave the y face's wall and the
    cell walks the x face's (trial9). Every kernel now gives the x face's."""
    H = np.zeros((5, 5))
    H[2, 2] = 3
    o = [[0, 0, 0.1], [4, 0, 0.1], [4.5, 4.5, 0.1], [0, 0, 0.1]]
    d = [[1, 1, 0], [-1, 1, 0], [-1, -1, 0], [1, 2, 0]]
    want = None
    for name in STRICT:
        got = algos.intersect(name, H, o, d, surface="flat", outputs=("t", "cell", "normal"))
        assert got.normal[:3, 1].tolist() == [0.0, 0.0, 0.0], name
        assert got.normal[:3, 0].tolist() == [-1.0, 1.0, 1.0], name
        if want is None:
            want = got.normal
        assert np.array_equal(got.normal, want), name
