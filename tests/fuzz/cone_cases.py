"""The cone kernel's invariants for the fuzz harness, as a function the harness
calls on every decoded first-hit case.

The harness reaches the cone kernel by itself (its decoder picks intersectors from
``algos.INTERSECTOR_REGISTRY``, and ``algos.intersect("cone", ...)`` runs the C entry
``_kernels.intersect_cone``); what it cannot know is what the cone must agree with. The
cone kernel skips only where its cones prove the ray clear of the solid and finishes
with the cell walk, so on every input it must give dda's hits: the same rays hit, at the
same t to the brute-force tolerance of tests/first_hits/test_intersect.py, in the same cell when t
is equal.

The harness (``tests/fuzz/harness.py``) calls it after the generic invariants of every
"intersect" case.
"""
from __future__ import annotations

import numpy as np

#: the kernel whose hits the cone kernel must reproduce
REFERENCE = "dda"


def check_cone(case: dict, call) -> None:
    """Assert that ``cone`` and :data:`REFERENCE` agree on a decoded first-hit ``case``.

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
        With the case's rays in full precision when the two kernels disagree, or when
        only one of them refuses the input.
    """
    if case.get("op") != "intersect":
        return
    outcomes = []
    for kernel in ("cone", REFERENCE):
        try:
            outcomes.append(call(case, kernel))
        except (ValueError, TypeError) as exc:
            outcomes.append(exc)
    cone, ref = outcomes
    if isinstance(cone, Exception) or isinstance(ref, Exception):
        assert type(cone) is type(ref), f"cone: {cone!r}, {REFERENCE}: {ref!r}"
        return
    if cone.t is None or ref.t is None:
        return
    hit_cone, hit_ref = np.isfinite(cone.t), np.isfinite(ref.t)
    both = hit_cone & hit_ref
    close = np.abs(cone.t[both] - ref.t[both]) <= 1e-9 * (1 + np.abs(ref.t[both]))
    bad = np.nonzero(hit_cone != hit_ref)[0].tolist() + np.nonzero(both)[0][~close].tolist()
    if bad:
        k = bad[0]
        o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)[k]
        d = np.asarray(case["directions"], dtype=float).reshape(-1, 3)[k]
        raise AssertionError(
            f"cone and {REFERENCE} differ on {len(bad)} rays ({case['surface']}); first: "
            f"origin={o.tolist()!r} direction={d.tolist()!r} cone t={cone.t[k]!r} "
            f"{REFERENCE} t={ref.t[k]!r}")
