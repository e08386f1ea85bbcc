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

#: the kernel whose outputs pitched_maxmip must reproduce bit for bit
REFERENCE = "dda_maxmip"


def _eye_batch(case: dict) -> dict:
    """The case with every origin replaced by the first ray's (one eye)."""
    o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)
    if len(o) == 0:
        return case
    return dict(case, origins=np.tile(o[0], (len(o), 1)))


def _assert_same(case, want, got, what):
    for name in ("t", "cell", "normal"):
        a, b = getattr(want, name), getattr(got, name)
        if a is None:
            continue
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            raise AssertionError(f"{name} ({what}): shapes {a.shape} and {b.shape} differ")
        if a.size == 0:  # an empty batch: nothing to differ in
            continue
        bad = np.nonzero((a.view(np.uint8) != b.view(np.uint8)).reshape(len(a), -1).any(axis=1))[0]
        if len(bad):
            k = int(bad[0])
            o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)[k]
            d = np.asarray(case["directions"], dtype=float).reshape(-1, 3)[k]
            raise AssertionError(
                f"pitched_maxmip and {REFERENCE} differ in {name} ({what}), {len(bad)} rays; "
                f"first: ray {k}, origin={o.tolist()!r} direction={d.tolist()!r}, "
                f"surface={case['surface']!r}: {REFERENCE} {a[k]!r}, pitched_maxmip {b[k]!r}")


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
    for what, batch in (("the case's rays", case), ("its one-eye batch", _eye_batch(case))):
        outcomes = []
        for kernel in (REFERENCE, "pitched_maxmip"):
            try:
                outcomes.append(call(batch, kernel))
            except (ValueError, TypeError) as exc:
                outcomes.append(exc)
        want, got = outcomes
        if isinstance(want, Exception) or isinstance(got, Exception):
            assert isinstance(want, Exception) and isinstance(got, Exception), \
                f"only one of {REFERENCE} and pitched_maxmip refused {what}: {want!r} {got!r}"
            continue
        _assert_same(batch, want, got, what)
