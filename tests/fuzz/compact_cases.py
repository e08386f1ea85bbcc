"""The dda_compact kernel's invariant for the fuzz harness, as a
function the harness calls on every decoded first-hit case.

The harness reaches ``dda_compact`` by itself (its decoder picks intersectors from
``algos.INTERSECTOR_REGISTRY``, and ``algos.intersect("dda_compact", ...)`` runs the C
entry ``_kernels.intersect_compact``); what it cannot know is what the kernel must agree
with. ``dda_compact`` culls only where its conservative tree bounds prove the ray clear of
the solid and hands every other cell, in the same order, to the exact cell test that
``dda_maxmip`` uses, so on every input it must give ``dda_maxmip``'s hits bit for bit:
the same t (NaN-aware) and the same cell.
"""
from __future__ import annotations

import numpy as np

#: the kernel whose hits dda_compact must reproduce bit for bit
REFERENCE = "dda_maxmip"


def check_compact(case: dict, call) -> None:
    """Assert that ``dda_compact`` and :data:`REFERENCE` agree on a decoded first-hit
    ``case``.

    Parameters
    ----------
    case : dict
        A decoded case of the fuzz harness; only ``case["op"] == "intersect"`` is checked.
    call : callable
        ``call(case, kernel)`` runs the case with another kernel and returns its
        ``algos.Hits`` (the harness's ``_call``); it raises ``ValueError`` or
        ``TypeError`` on input that every kernel refuses.

    Raises
    ------
    AssertionError
        With the case's first differing ray in full precision, or when only one of the
        two kernels refuses the input.
    """
    if case.get("op") != "intersect":
        return
    outcomes = []
    for kernel in ("dda_compact", REFERENCE):
        try:
            outcomes.append(call(case, kernel))
        except (ValueError, TypeError) as exc:
            outcomes.append(exc)
    compact, ref = outcomes
    if isinstance(compact, Exception) or isinstance(ref, Exception):
        assert type(compact) is type(ref), f"dda_compact: {compact!r}, {REFERENCE}: {ref!r}"
        return
    for name in ("t", "cell", "normal"):
        a, b = getattr(compact, name), getattr(ref, name)
        if a is None or b is None or len(a) == 0:
            continue
        same = (a == b) | (np.isnan(a) & np.isnan(b)) if a.dtype.kind == "f" else a == b
        same = same.reshape(len(a), -1).all(axis=1)
        if not same.all():
            k = int(np.nonzero(~same)[0][0])
            o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)[k]
            d = np.asarray(case["directions"], dtype=float).reshape(-1, 3)[k]
            raise AssertionError(
                f"dda_compact and {REFERENCE} differ in {name} on {int((~same).sum())} rays "
                f"({case['surface']}); first: origin={o.tolist()!r} direction={d.tolist()!r} "
                f"dda_compact {a[k]!r} {REFERENCE} {b[k]!r}")
