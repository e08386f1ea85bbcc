"""Helpers shared by the tests: the exact expectation for a batch, and reproducers."""
from __future__ import annotations

import numpy as np

import algos


def rounded(origins, directions):
    """The rays an exact kernel walks (algos.lattice)."""
    return algos.quantize(origins, directions)


def as_tuples(array) -> list:
    return [tuple(int(v) for v in row) for row in np.asarray(array).tolist()]


def reproducer(name, shape, origin, direction, tmin=None, tmax=None, seed=None) -> str:
    """A failure message that reproduces the case: algorithm, seed, grid, ray."""
    parts = [f"algorithm={name!r}", f"shape={tuple(shape)!r}",
             f"origin=({origin[0]!r}, {origin[1]!r})",
             f"direction=({direction[0]!r}, {direction[1]!r})"]
    if tmin is not None:
        parts.append(f"tmin={float(tmin)!r}")
    if tmax is not None:
        parts.append(f"tmax={float(tmax)!r}")
    if seed is not None:
        parts.append(f"seed={seed!r}")
    return ", ".join(parts)


def expected_cells(origins, directions, shape, tmin=None, tmax=None, exact=True):
    """reference_cells for each ray (of the lattice-rounded ray when exact)."""
    o, d = (rounded(origins, directions) if exact
            else (np.asarray(origins, float), np.asarray(directions, float)))
    n = len(o)
    lo = np.zeros(n) if tmin is None else np.broadcast_to(np.asarray(tmin, float), (n,))
    hi = np.full(n, np.inf) if tmax is None else np.broadcast_to(np.asarray(tmax, float), (n,))
    return [algos.reference_cells(o[k], d[k], shape, lo[k], hi[k]) for k in range(n)], o, d


def assert_paths_equal(name, got_paths, expected, origins, directions, shape, tmin=None,
                       tmax=None, seed=None, what="cells"):
    """Compare per ray; the message of the first mismatch is a reproducer."""
    n = len(expected)
    mismatches = [k for k in range(n) if as_tuples(got_paths[k]) != expected[k]]
    if mismatches:
        k = mismatches[0]
        lo = None if tmin is None else np.broadcast_to(tmin, (n,))[k]
        hi = None if tmax is None else np.broadcast_to(tmax, (n,))[k]
        raise AssertionError(
            f"{len(mismatches)} of {n} rays differ in {what}; first: "
            + reproducer(name, shape, origins[k], directions[k], lo, hi, seed)
            + f"\n expected {expected[k][:12]}{' ...' if len(expected[k]) > 12 else ''}"
            + f"\n got      {as_tuples(got_paths[k])[:12]}"
        )


def first_hit_fields(shape):
    """The six small fields of the first-hit tests (heights roughly in [0, 8]), by name:
    fBm, terraces, uniform random, a spike, flat and a tilted plane, all seeded."""
    from datasets_gen import fields

    return {
        "fbm": fields.generate("fbm", shape, seed=3, amplitude=6.0, scale=16.0),
        "terraces": fields.generate("terraces", shape, seed=4, amplitude=6.0, scale=16.0),
        "uniform": fields.generate("uniform", shape, seed=5, high=6.0),
        "spike": fields.generate("spike", shape, height=8.0, radius=9.0),
        "flat": fields.generate("flat", shape, height=2.0),
        "tilted": fields.generate("tilted_plane", shape, slope_x=0.1, slope_y=-0.05, height=1.0),
    }


#: The surfaces that jump at cell borders, where which cell holds a border point matters.
JUMPING_SURFACES = ("flat", "plane3")

