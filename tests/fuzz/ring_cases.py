"""The ring_maxmip kernel's invariant for the fuzz harness, as a function the harness calls
on every decoded first-hit case.

``ring_maxmip`` is not drawn by the decoder (that would remap the committed corpus).
Instead every ``dda_maxmip`` case is run again with it, twice: on the case's own rays
(fewer than the ring's slots, most often: the ring never fills), and on a longer batch
made from them (the case's rays repeated five times, in a shuffled order, with their tmin
and tmax), where finished slots take new rays and the ring drains at the end. Both must
give ``dda_maxmip``'s t, cell and normal bit for bit, and the statistics too when the
case asks for them (each ray's work is its own: the same steps as ``dda_maxmip``).
"""
from __future__ import annotations

import numpy as np

# the reference kernel and the bit-for-bit comparison are the plane kernel's cases'
from .plane_cases import REFERENCE, compare_batches

#: copies of the case's rays in the long batch (more than the ring's 8 slots for any case)
_COPIES = 5


def _long_batch(case: dict) -> dict:
    """The case's rays repeated _COPIES times, shuffled (seeded by the ray count)."""
    o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)
    d = np.asarray(case["directions"], dtype=float).reshape(-1, 3)
    n = len(o)
    order = np.random.default_rng(n).permutation(n * _COPIES)
    out = dict(case, origins=np.tile(o, (_COPIES, 1))[order],
               directions=np.tile(d, (_COPIES, 1))[order])
    for key in ("tmin", "tmax"):
        value = case.get(key)
        if value is not None and np.ndim(value) == 1 and len(value) == n:
            out[key] = np.tile(np.asarray(value, dtype=float), _COPIES)[order]
    return out


def _stats_equal(batch, call, what) -> None:
    """The statistics of both kernels on ``batch``, equal (when the case asks for them)."""
    try:
        want, got = call(batch, REFERENCE), call(batch, "ring_maxmip")
    except (ValueError, TypeError):
        return  # compare_batches has checked that both refuse it
    if getattr(want, "stats", None) is None:
        return
    for name in want.stats:
        a, b = np.asarray(want.stats[name]), np.asarray(got.stats[name])
        bad = np.nonzero(a != b)[0]
        assert not len(bad), (f"ring_maxmip and {REFERENCE} differ in stats {name!r} ({what}), "
                              f"{len(bad)} rays; first: ray {int(bad[0])}, "
                              f"{REFERENCE} {a[bad[0]]!r}, ring_maxmip {b[bad[0]]!r}")


def check_ring(case: dict, call) -> None:
    """Assert that ``ring_maxmip`` gives :data:`REFERENCE`'s outputs on a decoded
    ``dda_maxmip`` case and on its long batch.

    Parameters
    ----------
    case : dict
        A decoded case of the fuzz harness; only ``dda_maxmip`` first-hit cases are used.
    call : callable
        ``call(case, kernel)`` returns the case's ``algos.Hits`` with ``kernel`` (the
        harness's ``_call``); it raises ``ValueError`` or ``TypeError`` on refused input.

    Raises
    ------
    AssertionError
        With the first differing ray in full precision, or when only one of the two
        kernels refuses the input.
    """
    if case.get("op") != "intersect" or case.get("kernel") != REFERENCE:
        return
    batches = (("the case's rays", case), ("its long batch", _long_batch(case)))
    compare_batches(batches, call, "ring_maxmip")
    for what, batch in batches:
        _stats_equal(batch, call, what)
