"""The chain walk's strips for the fuzz harness, as a function the harness calls on every
decoded horizon case.

The horizon cases already reach ``horizon_chain`` through ``algos.horizon`` (the registry's
``chain``), and its angles are compared with every other exact method there. This adds
the strips' own entry points on the case's field and azimuth, with strips of the default
shape and of a shape drawn from the case (so the committed corpus decodes as before): the
frame (``horizon_strips_frame``), the build (``horizon_strips``), and the bound itself:
every level is the pairwise maximum of the one below, and the surface at each vertex's
far end and at the middle of its ray lies at most at the bins of its strip there.
"""
from __future__ import annotations

import math

import numpy as np

import algos.terrain as T
from algos import _kernels
from algos.terrain.grid import _prepare
from algos.terrain.walks import CHAIN_STRIP_BIN, CHAIN_STRIP_WIDTH, chain_strips

#: (width, bin) of the strips checked besides the default: picked by the case's height sum
_SHAPES = ((0.25, 0.5), (1.0, 1.0), (3.0, 8.0))


def _surface(h: np.ndarray, x: float, y: float) -> float:
    """The two-triangle surface (split u = v) at (x, y), from the cell holding it."""
    rows, cols = h.shape
    i, j = min(max(int(math.floor(x)), 0), cols - 2), min(max(int(math.floor(y)), 0), rows - 2)
    u, v = x - i, y - j
    h00, h10, h01, h11 = h[j, i], h[j, i + 1], h[j + 1, i], h[j + 1, i + 1]
    if u >= v:
        return h00 * (1 - u) + h10 * (u - v) + h11 * v
    return h00 * (1 - v) + h01 * (v - u) + h11 * u


def check_strips(case: dict) -> None:
    """Build and check the strips of a horizon case (see the module docstring); a field or
    azimuth that algos.horizon refuses is skipped."""
    if case.get("op") != "horizon":
        return
    try:
        h = _prepare(case["heights"], None).h
        d = T.azimuth_direction(case["azimuth"])
    except (ValueError, TypeError):
        return
    rows, cols = h.shape
    with np.errstate(all="ignore"):
        pick = int(abs(np.nansum(case["heights"])) * 7) % len(_SHAPES)
    for width, bin_length in ((CHAIN_STRIP_WIDTH, CHAIN_STRIP_BIN), _SHAPES[pick]):
        (data, offset, n_bins, _, _, ), _ = chain_strips(h, d, width, bin_length)
        c_min, a_min, n_strips, _ = _kernels.horizon_strips_frame(rows, cols, d.dx, d.dy, width,
                                                                  bin_length)
        levels = [data[offset[k]:offset[k] + n_strips * n_bins[k]].reshape(-1, n_strips).T
                  for k in range(len(n_bins))]
        assert levels[-1].shape == (n_strips, 1), "the top level is not one bin per strip"
        for below, above in zip(levels, levels[1:]):
            pad = np.full((n_strips, 2 * above.shape[1]), -np.inf)
            pad[:, :below.shape[1]] = below
            assert np.array_equal(above, pad.reshape(n_strips, -1, 2).max(axis=2)), \
                "a strip level is not the pairwise maximum of the one below"
        for j in range(rows):
            for i in range(cols):
                tx = ((cols - 1 - i) / d.dx if d.dx > 0 else -i / d.dx if d.dx < 0 else math.inf)
                ty = ((rows - 1 - j) / d.dy if d.dy > 0 else -j / d.dy if d.dy < 0 else math.inf)
                t_end = min(tx, ty)
                strip = int(math.floor((d.dx * j - d.dy * i - c_min) / width))
                along = d.dx * i + d.dy * j - a_min
                for t in (0.5 * t_end, t_end):
                    x = min(max(i + t * d.dx, 0.0), cols - 1.0)
                    y = min(max(j + t * d.dy, 0.0), rows - 1.0)
                    s = _surface(h, x, y)
                    for k, level in enumerate(levels):
                        slot = min(int((along + t) // (bin_length * 2 ** k)), level.shape[1] - 1)
                        # the bound, to the rounding of the surface's own evaluation
                        scale = 1e-12 * (1.0 + abs(s))
                        assert s <= level[strip, slot] + scale, \
                            f"strip bin below the surface: vertex ({i}, {j}) t={t!r} level {k}"
