"""The plane_maxmip kernel's invariant for the fuzz harness, as a function the harness
calls on every decoded first-hit case.

``plane_maxmip`` is not drawn by the decoder (that would remap the committed corpus).
Instead every ``dda_maxmip`` case is run again with it, three times: on the case's own
rays; on a batch of vertical planes grown from them (each ray joined by copies with the
same horizontal origin and direction, bit for bit, and other heights and slopes, in a
shuffled order, with the case's tmin and tmax), where the chained walks resume; and on
the same planes laid out as an image (row k holds copy k of every ray, as a camera lists
its columns), which takes the column path. All must give ``dda_maxmip``'s t, cell and
normal bit for bit.
"""
from __future__ import annotations

import numpy as np

#: the kernel whose outputs plane_maxmip must reproduce bit for bit
REFERENCE = "dda_maxmip"
#: each ray's plane: (oz offset, dz factor, dz offset) of its copies
_COPIES = ((0.0, 1.0, 0.0), (0.0, 0.5, 0.0), (0.0, 2.0, 0.0), (0.0, 1.0, 0.25),
           (0.0, 1.0, -0.25), (1.0, 1.0, 0.0), (-1.0, 1.0, 0.0), (0.5, 0.5, 0.125))


def _plane_batch(case: dict) -> dict:
    """The case with every ray grown into a plane of len(_COPIES) rays, shuffled."""
    o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)
    d = np.asarray(case["directions"], dtype=float).reshape(-1, 3)
    n = len(o)
    oz_off, dz_scale, dz_off = (np.array(c) for c in zip(*_COPIES))
    with np.errstate(all="ignore"):
        po = np.repeat(o, len(_COPIES), axis=0)
        pd = np.repeat(d, len(_COPIES), axis=0)
        po[:, 2] = po[:, 2] + np.tile(oz_off, n)
        pd[:, 2] = pd[:, 2] * np.tile(dz_scale, n) + np.tile(dz_off, n)
    order = np.random.default_rng(n).permutation(len(po))
    out = dict(case, origins=po[order], directions=pd[order])
    for key in ("tmin", "tmax"):
        value = case.get(key)
        if value is not None and np.ndim(value) == 1 and len(value) == n:
            out[key] = np.repeat(np.asarray(value, dtype=float), len(_COPIES))[order]
    return out


def _image_batch(case: dict) -> dict:
    """The plane batch of :func:`_plane_batch` unshuffled and laid out as a row-major
    image: column k is ray k's plane, row r its copy r (so heights and slopes come in no
    particular order down a column)."""
    o = np.asarray(case["origins"], dtype=float).reshape(-1, 3)
    n, rows = len(o), len(_COPIES)
    grown = _plane_batch(dict(case, origins=o, directions=case["directions"]))
    # undo the shuffle, then list copy r of every ray as row r
    order = np.random.default_rng(n).permutation(n * rows)
    batch = np.empty(n * rows, dtype=int)
    batch[order] = np.arange(n * rows)
    image = batch.reshape(n, rows).T.reshape(-1)
    out = dict(case, origins=grown["origins"][image], directions=grown["directions"][image])
    for key in ("tmin", "tmax"):
        value = grown.get(key)
        if value is not case.get(key):
            out[key] = np.asarray(value)[image]
    return out


def assert_same(case, want, got, what, kernel="plane_maxmip"):
    """Assert bit-identical t, cell and normal of ``kernel`` (``got``) and
    :data:`REFERENCE` (``want``) on ``case``'s rays; the first differing ray in full
    precision otherwise. Shared with the pitched kernel's cases."""
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
                f"{kernel} and {REFERENCE} differ in {name} ({what}), {len(bad)} rays; "
                f"first: ray {k}, origin={o.tolist()!r} direction={d.tolist()!r}, "
                f"surface={case['surface']!r}: {REFERENCE} {a[k]!r}, {kernel} {b[k]!r}")


def compare_batches(batches, call, kernel) -> None:
    """For each ``(what, batch)``: ``kernel`` and :data:`REFERENCE` both refuse it, or give
    bit-identical outputs (:func:`assert_same`)."""
    for what, batch in batches:
        outcomes = []
        for name in (REFERENCE, kernel):
            try:
                outcomes.append(call(batch, name))
            except (ValueError, TypeError) as exc:
                outcomes.append(exc)
        want, got = outcomes
        if isinstance(want, Exception) or isinstance(got, Exception):
            assert isinstance(want, Exception) and isinstance(got, Exception), \
                f"only one of {REFERENCE} and {kernel} refused {what}: {want!r} {got!r}"
            continue
        assert_same(batch, want, got, what, kernel)


def check_plane(case: dict, call) -> None:
    """Assert that ``plane_maxmip`` gives :data:`REFERENCE`'s outputs on a decoded
    ``dda_maxmip`` case and on its plane batch.

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
    compare_batches((("the case's rays", case), ("its plane batch", _plane_batch(case)),
                     ("its plane batch as an image", _image_batch(case))),
                    call, "plane_maxmip")
