"""Argument validators of the public API: one home, used by every public function.

Each validator either returns the argument converted to what the C layer expects or
raises ``ValueError``/``TypeError`` whose message names the argument and the offending
ray, sample or value (docs/CONVENTIONS.md, "Public API"). Nothing here is specific to one
kernel family.
"""
from __future__ import annotations

import math
import numbers

import numpy as np

from .lattice import MAX_DIRECTION, MAX_GRID_SIDE, MAX_ORIGIN

__all__ = ["as_float_array", "first_bad", "check_rays", "check_rays3", "check_t", "check_rising_from_below",
           "check_shape", "check_heights", "check_length", "check_spacing",
           "check_positive_int"]


def as_float_array(value, name: str) -> np.ndarray:
    """``value`` as a NumPy array of real numbers (any int, uint or float dtype), not
    copied when it already is one. Raises TypeError naming ``name`` otherwise."""
    try:
        array = np.asarray(value)
    except Exception as exc:  # e.g. ragged nested lists
        raise TypeError(f"{name}: cannot be read as an array ({exc})") from None
    if array.dtype == object and array.size and all(
            isinstance(v, numbers.Real) and not isinstance(v, (bool, np.bool_)) for v in array.flat):
        # Python numbers NumPy keeps as objects: an int beyond int64 (2**70), a Fraction.
        # They are real numbers: converted, or refused naming the one beyond float64
        values = []
        for index, v in zip(np.ndindex(array.shape), array.flat):
            try:
                values.append(float(v))
            except OverflowError:
                where = ", ".join(str(i) for i in index)
                text = str(v) if len(str(v)) <= 24 else f"{str(v)[:12]}... ({len(str(v))} digits)"
                raise ValueError(f"{name}: {name}[{where}] = {text} is beyond float64's range") from None
        return np.array(values, dtype=np.float64).reshape(array.shape)
    if array.dtype.kind not in "fiu":
        raise TypeError(f"{name}: expected real numbers, got dtype {array.dtype}")
    return array


def first_bad(mask: np.ndarray) -> tuple:
    """The index (a tuple of ints) of the first True of ``mask`` in C order."""
    index = np.argwhere(mask)[0]
    return tuple(int(v) for v in index)


def refuse_masked(value, name: str) -> None:
    """Raise ValueError naming the first masked entry of a masked array ``value`` (rays and
    ranges have no voids: a mask would otherwise be ignored silently)."""
    if isinstance(value, np.ma.MaskedArray):
        mask = np.ma.getmaskarray(value)
        if mask.any():
            where = ", ".join(str(i) for i in first_bad(mask))
            raise ValueError(f"{name}: {name}[{where}] is masked; rays and ranges have no "
                             f"voids, so fill the masked values or drop those rays")


def check_rays(origins, directions, width: int):
    """Validated C-contiguous native float64 copies of (N, ``width``) ray arrays of a
    traversal: finite, ``|origins[:, :2]| <= 2**30`` and ``|directions| <= 2**1000``."""
    arrays = []
    for name, value in (("origins", origins), ("directions", directions)):
        refuse_masked(value, name)
        array = as_float_array(value, name)
        if array.ndim != 2 or array.shape[1] != width:
            raise ValueError(f"{name}: expected shape (N, {width}), got {array.shape}")
        array = np.ascontiguousarray(array, dtype=np.float64)
        bad = ~np.isfinite(array)
        if bad.any():
            k, c = first_bad(bad)
            raise ValueError(
                f"{name}: ray {k} has a non-finite component {name}[{k}, {c}] = {array[k, c]}"
            )
        arrays.append(array)
    o, d = arrays
    if len(o) != len(d):
        raise ValueError(f"origins and directions: {len(o)} origins but {len(d)} directions")
    huge = np.abs(d) > MAX_DIRECTION
    if huge.any():
        k, c = first_bad(huge)
        raise ValueError(
            f"directions: ray {k} has |directions[{k}, {c}]| = {abs(d[k, c])} > 2**1000, "
            "the documented limit (scale the direction and t together)"
        )
    far = np.abs(o[:, :2]) > MAX_ORIGIN
    if far.any():
        k, c = first_bad(far)
        raise ValueError(
            f"origins: ray {k} has |origins[{k}, {c}]| = {abs(o[k, c])} > 2**30, the "
            "documented limit (move the origin along the ray toward the grid)"
        )
    return o, d


#: The range of a first-hit direction's largest |component|: below it ``t`` can overflow
#: (a hit past 2**1023 reads as a miss) and a bilinear cell's quadratic, whose leading
#: coefficient scales as |d|^2, underflows; above it that coefficient overflows.
MIN_HIT_DIRECTION, MAX_HIT_DIRECTION = 2.0 ** -400, 2.0 ** 400


def check_rays3(origins, directions):
    """Validated (N, 3) float64 rays of a first-hit query: finite, no zero direction,
    each direction's largest |component| in ``[2**-400, 2**400]``, ``|origins| <= 2**30``."""
    arrays = []
    for name, value in (("origins", origins), ("directions", directions)):
        refuse_masked(value, name)
        array = as_float_array(value, name)
        if array.ndim != 2 or array.shape[1] != 3:
            raise ValueError(f"{name}: expected shape (N, 3), got {array.shape}")
        array = np.ascontiguousarray(array, dtype=np.float64)
        bad = ~np.isfinite(array)
        if bad.any():
            k, c = first_bad(bad)
            raise ValueError(f"{name}: ray {k} has a non-finite component {name}[{k}, {c}] = {array[k, c]}")
        arrays.append(array)
    o, d = arrays
    if len(o) != len(d):
        raise ValueError(f"origins and directions: {len(o)} origins but {len(d)} directions")
    zero = np.all(d == 0, axis=1)
    if zero.any():
        k = int(np.argmax(zero))
        raise ValueError(f"directions: ray {k} is the zero vector")
    largest = np.max(np.abs(d), axis=1) if len(d) else np.zeros(0)
    scale = (largest < MIN_HIT_DIRECTION) | (largest > MAX_HIT_DIRECTION)
    if scale.any():
        k = int(np.argmax(scale))
        raise ValueError(f"directions: ray {k} has a largest component max |directions[{k}, :]| = "
                         f"{float(largest[k])!r} outside [2**-400, 2**400], the documented range "
                         "(t is in units of d: scale the direction, and t with it)")
    far = np.abs(o) > MAX_ORIGIN
    if far.any():
        k, c = first_bad(far)
        raise ValueError(f"origins: ray {k} has |origins[{k}, {c}]| = {abs(o[k, c])} > 2**30, the "
                         "documented limit (start the ray nearer the grid, at o + s d, and add s "
                         "to its t)")
    return o, d


def check_t(value, name: str, n: int):
    """None, or a float64 (n,) array from a scalar or an (n,) array without NaN."""
    if value is None:
        return None
    refuse_masked(value, name)
    array = as_float_array(value, name)
    if array.ndim == 0:
        array = np.full(n, float(array))
    if array.shape != (n,):
        raise ValueError(f"{name}: expected a scalar or shape ({n},), got {array.shape}")
    array = np.ascontiguousarray(array, dtype=np.float64)
    bad = np.isnan(array)
    if bad.any():
        k = first_bad(bad)[0]
        raise ValueError(f"{name}: ray {k} has {name}[{k}] = nan")
    return array


def check_rising_from_below(directions, tmin, tmax=None):
    """ValueError naming ``tmin`` and the first ray that rises vertically (direction
    ``(0, 0, dz > 0)``) over a range starting at ``tmin = -inf`` (``tmax`` above it): it
    starts infinitely deep inside the solid, so its first hit would be at ``t = -inf``,
    a point of no cell. Every finite ``tmin`` is a hit there, in the cell under the origin
    (docs/CONVENTIONS.md, "A ray that starts inside the solid hits at t0"); the kernels
    and the brute force disagreed on this limit (a miss, or a hit in cell (0, 0))."""
    if tmin is None:
        return
    d = np.asarray(directions)
    bad = (np.isneginf(tmin) & (d[:, 0] == 0) & (d[:, 1] == 0) & (d[:, 2] > 0))
    if tmax is not None:
        bad &= tmax > tmin
    if bad.any():
        k = first_bad(bad)[0]
        raise ValueError(f"tmin: ray {k} rises vertically from tmin[{k}] = -inf, infinitely "
                         "deep inside the solid, so its first hit would be at t = -inf; give a "
                         "finite tmin (any finite one hits there, in the cell under the origin)")


def check_shape(shape) -> tuple[int, int]:
    """A 2D grid's ``(nx, ny)`` in cells, each an integer in ``[1, 2**24]``."""
    try:
        nx, ny = shape
    except (TypeError, ValueError):
        raise ValueError(f"shape: expected (nx, ny), got {shape!r}") from None
    sides = []
    for k, side in enumerate((nx, ny)):
        if isinstance(side, bool) or not isinstance(side, numbers.Integral):
            raise TypeError(f"shape: shape[{k}] must be an integer, got {side!r}")
        side = int(side)
        if side < 1:
            raise ValueError(f"shape: shape[{k}] = {side}; a grid needs at least one cell")
        if side > MAX_GRID_SIDE:
            raise ValueError(f"shape: shape[{k}] = {side} exceeds the limit 2**24 = {MAX_GRID_SIDE}")
        sides.append(side)
    return sides[0], sides[1]


def check_heights(heights, name: str = "heights", *, dtype=np.float32, finite=True,
                  band_samples: int = 1 << 20) -> np.ndarray:
    """A 2D height array of at least 2 x 2 and at most 2**24 samples per side, as a
    C-contiguous aligned native array of ``dtype`` (not copied when it already is one: a
    memory-mapped file stays mapped). With ``finite`` every sample must be finite; the
    check runs in bands of ``band_samples`` (bounded temporaries) and names the first
    bad (row, col)."""
    h = as_float_array(heights, name)
    if h.ndim != 2:
        raise ValueError(f"{name}: expected a 2D array (rows, cols), got shape {h.shape}")
    if h.shape[0] < 2 or h.shape[1] < 2:
        raise ValueError(f"{name}: a height field needs at least 2 x 2 samples, got {h.shape}")
    if max(h.shape) > MAX_GRID_SIDE:
        raise ValueError(f"{name}: shape {h.shape} exceeds the limit of 2**24 samples per side")
    source = h
    with np.errstate(over="ignore"):  # a finite sample beyond float32 is named below
        h = np.require(h, dtype=dtype, requirements=["C", "A"])
    if finite:
        step = max(1, band_samples // h.shape[1])
        for r0 in range(0, h.shape[0], step):
            bad = ~np.isfinite(h[r0:r0 + step])
            if bad.any():
                row, col = first_bad(bad)
                row += r0
                if np.isfinite(source[row, col]):
                    raise ValueError(f"{name}: sample (row {row}, col {col}) = "
                                     f"{float(source[row, col]):g} is beyond the range of "
                                     f"{np.dtype(dtype).name}, the type heights are kept in")
                raise ValueError(f"{name}: sample (row {row}, col {col}) is {h[row, col]}; "
                                 "heights must be finite here (a HeightField carries a void "
                                 "mask for nodata, which the terrain products accept)")
    return h


def check_length(value, name: str, *, allow_none=True, allow_zero=True):
    """A non-negative length as a float; None (and ``inf`` when ``allow_none``) means
    unlimited and gives None."""
    if value is None:
        if allow_none:
            return None
        raise ValueError(f"{name}: a number is required")
    if isinstance(value, bool):
        raise TypeError(f"{name}: expected a number, got {value!r}")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise TypeError(f"{name}: expected a number, got {value!r}") from None
    if math.isnan(v) or v < 0 or (v == 0 and not allow_zero):
        raise ValueError(f"{name}: expected a {'non-negative' if allow_zero else 'positive'} "
                         f"length, got {value!r}")
    if math.isinf(v):
        if allow_none:
            return None
        raise ValueError(f"{name}: expected a finite length, got {value!r}")
    return v


def check_spacing(spacing, name: str = "spacing") -> tuple[float, float]:
    """``(dx, dy)`` from one number (square pixels) or a pair, each positive and finite."""
    if isinstance(spacing, (bool, str, bytes)):
        raise TypeError(f"{name}: expected a length or (dx, dy), got {spacing!r}")
    if np.ndim(spacing) == 0:
        pair, labels = (spacing, spacing), (name, name)
    else:
        pair = tuple(np.asarray(spacing).ravel().tolist()) if np.ndim(spacing) == 1 else None
        if pair is None or len(pair) != 2:
            raise ValueError(f"{name}: expected one length or (dx, dy), got {spacing!r}")
        labels = (f"{name}[0]", f"{name}[1]")
    out = []
    for label, v in zip(labels, pair):
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise TypeError(f"{name}: {label} must be a number, got {v!r}") from None
        if not (math.isfinite(v) and v > 0):
            raise ValueError(f"{name}: {label} = {v!r}; a pixel size must be a positive finite length")
        out.append(v)
    return out[0], out[1]


def check_positive_int(value, name: str) -> int:
    """A positive int (bool refused)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise ValueError(f"{name}: expected a positive int, got {value!r}")
    return int(value)
