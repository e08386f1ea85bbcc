"""The products over many azimuths (sky-view factor, openness) share one prologue: the
azimuths they compute (equally spaced, rational, snapped or explicit) and one DataArray
path. Both products must read their arguments alike, bit for bit and word for word."""
from __future__ import annotations

import numpy as np
import pytest

import algos.terrain as T
from algos.terrain.azimuths import _product_azimuths

PRODUCTS = [("sky_view_factor", T.sky_view_factor, {}),
            ("openness", T.openness, {}),
            ("openness_negative", T.openness, dict(kind="negative", units="radians"))]


def _heights():
    return np.random.default_rng(7).random((12, 15)) * 5.0


@pytest.mark.parametrize("name, product, extra", PRODUCTS, ids=[p[0] for p in PRODUCTS])
def test_the_azimuth_spellings_compute_the_same_azimuths(name, product, extra):
    """n_azimuths, rational and snap_denominator give bit for bit what the explicit
    azimuths they stand for give."""
    h = _heights()
    pairs = [
        (dict(n_azimuths=8), np.arange(8) * 45.0),
        (dict(n_azimuths=np.int64(5)), np.arange(5) * 72.0),
        (dict(n_azimuths=16, rational=True), T.rational_azimuths(16)),
        (dict(n_azimuths=16, snap_denominator=5),
         T.snap_azimuths(np.arange(16) * 22.5, 5)[0]),
        (dict(azimuths=[33.0, 200.0], snap_denominator=3),
         T.snap_azimuths([33.0, 200.0], 3)[0]),
        (dict(n_azimuths=6, spacing=(2.0, 1.0), snap_denominator=4),
         T.snap_azimuths(np.arange(6) * 60.0, 4, (2.0, 1.0))[0]),
    ]
    for spelled, azimuths in pairs:
        spacing = spelled.get("spacing")
        got = product(h, **spelled, **extra)
        expected = product(h, azimuths=azimuths, spacing=spacing, **extra)
        np.testing.assert_array_equal(got, expected, err_msg=f"{name} {spelled}")


@pytest.mark.parametrize("name, product, extra", PRODUCTS, ids=[p[0] for p in PRODUCTS])
def test_bad_azimuth_arguments_word_for_word(name, product, extra):
    h = _heights()
    cases = [
        (dict(n_azimuths=0), "ValueError: n_azimuths: expected a positive int, got 0"),
        (dict(n_azimuths=True), "ValueError: n_azimuths: expected a positive int, got True"),
        (dict(n_azimuths=2.5), "ValueError: n_azimuths: expected a positive int, got 2.5"),
        (dict(n_azimuths=4, snap_denominator=0),
         "ValueError: snap_denominator: expected an int in 1..128, got 0"),
        (dict(azimuths=[]),
         "ValueError: azimuths: expected a number or a non-empty 1D sequence, got shape (0,)"),
    ]
    for kwargs, expected in cases:
        with pytest.raises((TypeError, ValueError)) as caught:
            product(h, **kwargs, **extra)
        assert f"{caught.type.__name__}: {caught.value}" == expected, (name, kwargs)


def test_the_dataarray_attrs_keep_their_order():
    """The products' DataArray attrs, in order: the product's own first, then the
    azimuths, the distance, the curvature, the paths and the snapping."""
    xr = pytest.importorskip("xarray")
    h = _heights()
    da = xr.DataArray(h, dims=("y", "x"), attrs=dict(units="m"))
    svf = T.sky_view_factor(da, 4, snap_denominator=2)
    assert list(svf.attrs) == ["units", "product", "n_azimuths", "max_distance", "curvature",
                               "algorithm", "paths", "snapped_azimuths",
                               "snap_max_change_deg"]
    assert svf.attrs["units"] == "1" and svf.name == "sky_view_factor"
    neg, stats = T.openness(da, "negative", 4, 3.0, units="radians", return_stats=True)
    assert list(neg.attrs) == ["units", "product", "kind", "n_azimuths", "max_distance",
                               "curvature", "algorithm", "paths"]
    assert (neg.attrs["units"], neg.attrs["kind"], neg.attrs["max_distance"]) == (
        "radians", "negative", 3.0)
    assert neg.attrs["paths"] == ",".join(stats.paths)


def test_product_azimuths_returns_the_snapping_record():
    """_product_azimuths: the azimuths as given when explicit, and the snapping record
    exactly as snap_azimuths returns it."""
    h = _heights()
    explicit = [10.0, 100.0]
    azimuths, snap = _product_azimuths(h, None, explicit, False, None, None)
    assert azimuths is explicit and snap is None
    azimuths, snap = _product_azimuths(h, 16, None, False, None, 5)
    expected = T.snap_azimuths(np.arange(16) * 22.5, 5)
    np.testing.assert_array_equal(azimuths, expected[0])
    np.testing.assert_array_equal(snap[0], expected[0])
    assert snap[1] == expected[1]
