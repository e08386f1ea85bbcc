"""Huge-page allocations (algos.hugepages): aligned, zeroed on request, writable, and
invisible in every output: a field's structures and first hits are the same with them
and without."""
import numpy as np
import pytest

import algos
from algos import hugepages
from datasets_gen import fields


@pytest.mark.skipif(hugepages.ADVICE is None, reason="no MADV_HUGEPAGE on this platform")
def test_large_arrays_start_on_a_huge_page():
    a = hugepages.empty((1100, 600), np.float32)
    assert a.ctypes.data % hugepages.HUGE_PAGE == 0
    assert a.shape == (1100, 600) and a.dtype == np.float32 and a.flags.c_contiguous
    a[...] = 3.5
    assert float(a.sum()) == 3.5 * a.size
    z = hugepages.empty(3 << 20, np.uint8, zero=True)
    assert z.ctypes.data % hugepages.HUGE_PAGE == 0 and not z.any()


def test_small_arrays_are_plain():
    a = hugepages.empty((10, 10), np.float64, zero=True)
    assert a.shape == (10, 10) and not a.any() and a.flags.writeable


def test_adopt_never_copies_the_callers_array():
    h = np.zeros((1024, 1024), np.float32)
    assert hugepages.adopt(h, owner=h) is h
    moved = hugepages.adopt(h + 1)
    assert np.array_equal(moved, h + 1)


def test_outputs_unchanged(monkeypatch):
    """A field above a huge page: every structure and the first hits of the maxmip,
    plane and compact kernels equal those built on plain NumPy memory."""
    H = fields.generate("fbm", (1025, 1030), seed=4, amplitude=60.0, scale=128.0)
    rng = np.random.default_rng(5)
    o = np.column_stack([rng.uniform(0, 1029, 300), rng.uniform(0, 1024, 300),
                         np.full(300, 80.0)])
    d = np.column_stack([rng.normal(size=(300, 2)), rng.uniform(-0.3, -0.01, 300)])
    huge = algos.Field(H.astype(np.float64))
    results = {}
    for name in ("dda_maxmip", "plane_maxmip", "dda_compact"):
        results[name] = algos.intersect(name, huge, o, d, outputs=("t", "cell")).t
    monkeypatch.setattr(hugepages, "ADVICE", None)
    plain = algos.Field(H.astype(np.float64))
    for a, b in zip(huge.mip_for(), plain.mip_for()):
        assert np.array_equal(a, b)
    assert np.array_equal(huge.cell_heights, plain.cell_heights)
    for name, t in results.items():
        again = algos.intersect(name, plain, o, d, outputs=("t", "cell")).t
        assert np.array_equal(t.view(np.int64), again.view(np.int64)), name
