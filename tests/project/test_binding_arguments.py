"""The C binding's argument checks, pinned word for word (cext/binding/).

The terrain and first-hit entry points read their outputs, grids and structures through
the shared reader of args.h; the Python wrappers and the tests match its messages.
Each case below calls one private entry point with everything valid but one argument and
pins the exception's type and full message, so that a change to how the binding reads its
arguments cannot change what a caller sees.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

import algos
from algos import _kernels

ROWS, COLS = 4, 4
VERTICES = ROWS * COLS


def _read_only(array):
    array = array.copy()
    array.flags.writeable = False
    return array


def _swapped(array):
    return array.astype(array.dtype.newbyteorder())


def _bad_outputs(dtype):
    """(label, bad output) pairs for an output of VERTICES elements of `dtype` (a byte has
    no byte order to swap)."""
    other = np.float32 if dtype != np.float32 else np.float64
    swapped = [] if np.dtype(dtype).itemsize == 1 else [
        ("swapped", _swapped(np.zeros(VERTICES, dtype)))]
    return [
        ("none", None),
        ("list", [0.0] * VERTICES),
        ("dtype", np.zeros(VERTICES, other)),
        ("size", np.zeros(VERTICES - 1, dtype)),
        ("read_only", _read_only(np.zeros(VERTICES, dtype))),
        ("strided", np.zeros(2 * VERTICES, dtype)[::2]),
    ] + swapped


def _strips(h):
    """Valid chain-walk strips over the heights h for the direction (1, 0)."""
    from algos.terrain import azimuth_direction
    from algos.terrain.walks import chain_strips

    return chain_strips(h, azimuth_direction(90.0))[0]


def _terrain_calls():
    """(entry point, output dtype, call(out)) with every argument but `out` valid."""
    h = np.zeros((ROWS, COLS))
    one = np.ones(1)
    ints = [np.zeros(1, np.int64) for _ in range(4)]
    ones = np.ones(1, np.int64)
    limits = np.zeros(COLS, np.int64)
    return [
        ("horizon_pattern", np.float64, lambda out: _kernels.horizon_pattern(
            h, one, *ints, one, limits, limits.copy(), -1, 0.0, 0.0, 0.0, 0, 0, VERTICES, out)),
        ("horizon_sweep", np.float64, lambda out: _kernels.horizon_sweep(
            h, 1, 0, one, ones, ints[0], ones, ints[0], one, ones, ints[0], 1.0, 0, 1, out)),
        ("horizon_walk", np.float64, lambda out: _kernels.horizon_walk(
            h, None, 1.0, 0.0, math.inf, 0, VERTICES, out)),
        ("horizon_rows", np.float64, lambda out: _kernels.horizon_rows(
            h, one, *ints, one, ints[0], ints[0], 1, 1, 0, -1, 0.0, 0.0, 0, ROWS, out)),
        ("horizon_chain", np.float64, lambda out: _kernels.horizon_chain(
            h, _strips(h), 1.0, 0.0, math.inf, np.array([1], np.int64), np.array([0], np.int64),
            one, 2, 0, 1, out, np.zeros(VERTICES))),
        ("horizon_chain_occ", np.float64, lambda occ: _kernels.horizon_chain(
            h, _strips(h), 1.0, 0.0, math.inf, np.array([1], np.int64), np.array([0], np.int64),
            one, 2, 0, 1, np.zeros(VERTICES), occ)),
        ("viewshed", np.uint8, lambda out: _kernels.viewshed(
            h, None, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0, VERTICES, out)),
        ("viewshed_threshold", np.float64, lambda out: _kernels.viewshed_threshold(
            h, None, 1.0, 1.0, 0.0, 0.0, 0.0, 0, 0, VERTICES, out)),
        ("horizon_march", np.float64, lambda out: _kernels.horizon_march(
            h, 1.0, 0.0, 1.0, math.inf, 0.0, 0, VERTICES, out)),
    ]


def _message(call, argument):
    with pytest.raises((TypeError, ValueError)) as caught:
        call(argument)
    return f"{caught.type.__name__}: {caught.value}"


def _out_messages(name, dtype_name):
    """The messages of one output argument `name` of `dtype_name` and VERTICES elements."""
    layout = ("TypeError: {name}: expected a C-contiguous, aligned, native-order, writable "
              "array of dtype {dtype}")
    return {
        "none": f"TypeError: {name}: an array is required, not None",
        "list": f"TypeError: {name}: expected a numpy array, got list",
        "dtype": layout.format(name=name, dtype=dtype_name),
        "size": f"ValueError: {name}: expected {VERTICES} elements, got {VERTICES - 1}",
        "read_only": layout.format(name=name, dtype=dtype_name),
        "strided": layout.format(name=name, dtype=dtype_name),
        "swapped": layout.format(name=name, dtype=dtype_name),
    }


_TERRAIN_EXPECTED = {
    "horizon_chain_occ": _out_messages("occ", "float64"),
    "viewshed": {**_out_messages("out", "uint64"),
                 "list": "TypeError: out: expected a numpy array, got list"},
}


@pytest.mark.parametrize("entry, dtype, call", _terrain_calls(),
                         ids=[c[0] for c in _terrain_calls()])
def test_terrain_outputs_are_refused_word_for_word(entry, dtype, call):
    """Each terrain entry point refuses a bad output array with the shared reader's message
    (the dtype named as the reader names it: uint8 falls in its last, uint64, branch)."""
    expected = _TERRAIN_EXPECTED.get(entry, _out_messages("out", "float64"))
    for label, bad in _bad_outputs(dtype):
        got = _message(call, bad)
        assert got == expected[label], (entry, label, got)
    good = np.zeros(VERTICES, dtype)
    call(good)  # the valid call runs


def _intersect_run():
    from algos.intersect import prepare_intersect
    from algos.registry import get_intersector

    fld = algos.Field(np.zeros((ROWS, COLS)))
    o = np.array([[1.5, 2.5, 50.0], [3.25, 1.0, 40.0]])
    d = np.array([[0.6, 0.3, -1.0], [0.2, 0.7, -0.8]])
    return prepare_intersect(get_intersector("dda"), fld, "triangles", o, d, None, None,
                             ("t", "cell", "normal"), {"cull_cells": True})


#: (output index, name, dtype, elements per ray, dtype as the reader names it)
_HIT_OUTPUTS = [(0, "t", np.float64, 1, "float64"), (1, "cell", np.int32, 2, "int32"),
                (2, "normal", np.float64, 3, "float64"), (3, "stats", np.int64, 5, "int64")]


@pytest.mark.parametrize("index, name, dtype, per_ray, dtype_name", _HIT_OUTPUTS,
                         ids=[o[1] for o in _HIT_OUTPUTS])
def test_intersect_outputs_are_refused_word_for_word(index, name, dtype, per_ray, dtype_name):
    """intersect() takes each output as None or a writable array of per_ray elements a ray;
    anything else is refused with the shared reader's message."""
    run = _intersect_run()
    size = 2 * per_ray
    other = np.float32 if dtype != np.float32 else np.float64
    layout = (f"TypeError: {name}: expected a C-contiguous, aligned, native-order, writable "
              f"array of dtype {dtype_name}")
    cases = [
        ([0.0] * size, f"TypeError: {name}: expected a numpy array, got list"),
        (np.zeros(size, other), layout),
        (np.zeros(size + 1, dtype), f"ValueError: {name}: expected {size} elements, got {size + 1}"),
        (_read_only(np.zeros(size, dtype)), layout),
        (np.zeros(2 * size, dtype)[::2], layout),
        (_swapped(np.zeros(size, dtype)), layout),
    ]

    def call(bad):
        outputs = list(run.args[5])
        outputs[index] = bad
        return _kernels.intersect(*run.args[:5], tuple(outputs))

    for bad, expected in cases:
        assert _message(call, bad) == expected, (name, bad)
    assert call(None) >= 0  # None: not wanted
    assert call(np.zeros(size, dtype)) >= 0


def test_cone_and_compact_builders_refuse_word_for_word():
    """cone_relaxed_slopes and compact_build read cellmax as a 2D float32 grid, their
    outputs as writable arrays; the leading structure of intersect_cone and
    intersect_compact is required."""
    cellmax = np.zeros((3, 3), np.float32)
    slope = np.zeros((3, 3), np.float32)
    cases = [
        (lambda: _kernels.cone_relaxed_slopes(np.zeros(9, np.float32), 1, slope),
         "TypeError: cellmax: expected a 2D numpy array"),
        (lambda: _kernels.cone_relaxed_slopes(np.zeros((0, 3), np.float32), 1, slope),
         "ValueError: cellmax: each side must be in [1, 2^24 - 1]"),
        (lambda: _kernels.cone_relaxed_slopes(np.zeros((0, 3), np.float32), 0, slope),
         "ValueError: cellmax: each side must be in [1, 2^24 - 1]"),
        (lambda: _kernels.cone_relaxed_slopes(cellmax, 65, slope),
         "ValueError: radius: expected 1 to 64, got 65"),
        (lambda: _kernels.cone_relaxed_slopes(cellmax.astype(np.float64), 1, slope),
         "TypeError: cellmax: expected a C-contiguous native float32 array of 2 dims"),
        (lambda: _kernels.cone_relaxed_slopes(cellmax, 1, _read_only(slope)),
         "ValueError: slope: must be writable"),
        (lambda: _kernels.cone_relaxed_slopes(cellmax, 1, np.zeros((3, 4), np.float32)),
         "ValueError: slope: dimension 1 is 4, expected 3"),
        (lambda: _kernels.compact_build(np.zeros(9, np.float32), np.zeros(64, np.uint8)),
         "TypeError: cellmax: expected a 2D numpy array"),
        (lambda: _kernels.compact_build(np.zeros((3, 0), np.float32), np.zeros(64, np.uint8)),
         "ValueError: cellmax: each side must be in [1, 2^24 - 1]"),
        (lambda: _kernels.compact_build(cellmax, [0] * 64),
         "TypeError: compact: expected a numpy array, got list"),
        (lambda: _kernels.compact_build(cellmax, np.zeros(64, np.int8)),
         "TypeError: compact: expected a C-contiguous 1D uint8 array"),
        (lambda: _kernels.intersect_cone(),
         "TypeError: intersect_cone: expected cone, then intersect()'s arguments"),
        (lambda: _kernels.intersect_compact(),
         "TypeError: intersect_compact: expected compact, then intersect()'s arguments"),
    ]
    for call, expected in cases:
        with pytest.raises((TypeError, ValueError)) as caught:
            call()
        assert f"{caught.type.__name__}: {caught.value}" == expected
    assert _kernels.cone_relaxed_slopes(cellmax, 1, slope) >= 0


def test_sweep_and_row_breakpoints_are_refused_word_for_word():
    """The sweep and the row walk read their breakpoints alike: the first array sets their
    number, the interpolation arrays and both reaches must match it."""
    h = np.zeros((ROWS, COLS))
    one, ones, zero = np.ones(1), np.ones(1, np.int64), np.zeros(1, np.int64)
    out = np.zeros(VERTICES)

    def sweep(tf=one, dxa=ones, w=one, mx=ones, my=zero):
        return _kernels.horizon_sweep(h, 1, 0, tf, dxa, zero, ones, zero, w, mx, my, 1.0, 0, 1,
                                      out)

    def rows(inv=one, dxa=zero, w=one, rx=zero, ry=zero):
        return _kernels.horizon_rows(h, inv, dxa, zero, zero, zero, w, rx, ry, 1, 1, 0, -1, 0.0,
                                     0.0, 0, ROWS, out)

    two = np.ones(2, np.int64)
    cases = [
        (lambda: sweep(tf=np.ones(1, np.float32)), "TypeError: tfrac: expected a C-contiguous, "
         "aligned, native-order array of dtype float64"),
        (lambda: sweep(dxa=two), "ValueError: dx_a: expected 1 elements, got 2"),
        (lambda: sweep(w=np.ones(2)), "ValueError: w: expected 1 elements, got 2"),
        (lambda: sweep(mx=two), "ValueError: mx: expected 1 elements, got 2"),
        (lambda: sweep(my=None), "TypeError: my: an array is required, not None"),
        (lambda: rows(inv=[1.0]), "TypeError: inv_t: expected a numpy array, got list"),
        (lambda: rows(rx=np.zeros(1, np.int32)), "TypeError: rx: expected a C-contiguous, "
         "aligned, native-order array of dtype int64"),
        (lambda: rows(ry=two), "ValueError: ry: expected 1 elements, got 2"),
    ]
    for call, expected in cases:
        with pytest.raises((TypeError, ValueError)) as caught:
            call()
        assert f"{caught.type.__name__}: {caught.value}" == expected
    sweep()
    rows()
