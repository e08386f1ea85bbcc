"""The pitched_maxmip kernel's invariant for the fuzz harness, as a function the harness
calls on every decoded first-hit case.

``pitched_maxmip`` is not drawn by the decoder (that would remap the committed corpus).
Instead every ``dda_maxmip`` case is run again with it, twice: on the case's own rays
(rays from many origins: the per-ray fallback), and on the batch of one eye made from
them (every ray moved to the first ray's origin, with the case's directions, tmin and
tmax), where the coarse image bounds each walk's start. Both must give ``dda_maxmip``'s
t, cell and normal bit for bit.
"""
from __future__ import annotations

import numpy as np

# the reference kernel and the bit-for-bit comparison are the plane kernel's cases'
from .plane_cases import REFERENCE, compare_batches


def _eye_batch(case: dict) -> dict:
    """The case with every origin replaced by the first ray's (one eye)."""
    o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)
    if len(o) == 0:
        return case
    return dict(case, origins=np.tile(o[0], (len(o), 1)))


def check_pitched(case: dict, call) -> None:
    """Assert that ``pitched_maxmip`` gives :data:`REFERENCE`'s outputs on a decoded
    ``dda_maxmip`` case and on its one-eye batch.

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
    compare_batches((("the case's rays", case), ("its one-eye batch", _eye_batch(case))),
                    call, "pitched_maxmip")
