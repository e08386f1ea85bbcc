"""A NumPy plugin for hftrace: the cell DDA of Amanatides & Woo (1987), vectorised over
rays (every ray takes one step per iteration; finished rays drop out).

    import algos
    from examples.plugins.numpy_dda import register
    register()                          # algos.register_traversal("numpy_dda", ...)

or in a sweep config: ``plugins = ["examples.plugins.numpy_dda:register"]``.
"""
import numpy as np

import algos


def numpy_dda(origins, directions, shape):
    """Visited cells of every ray.

    Parameters
    ----------
    origins, directions : ndarray of float64, shape (N, 2)
    shape : (nx, ny)
        Cells along x and y.

    Returns
    -------
    list of ndarray of int64, shape (k, 2)
        The cells (i, j) of each ray in visiting order (the harness folds them into the
        visit checksum after the timed call).
    """
    size = np.array(shape, dtype=np.float64)
    o = np.asarray(origins, dtype=np.float64)
    d = np.asarray(directions, dtype=np.float64)
    n = len(o)
    t0, t1 = np.zeros(n), np.full(n, np.inf)
    live = np.ones(n, bool)
    with np.errstate(divide="ignore", invalid="ignore"):
        for a in range(2):
            moving = d[:, a] != 0
            ta = (0 - o[:, a]) / d[:, a]
            tb = (size[a] - o[:, a]) / d[:, a]
            t0 = np.where(moving, np.maximum(t0, np.minimum(ta, tb)), t0)
            t1 = np.where(moving, np.minimum(t1, np.maximum(ta, tb)), t1)
            live &= moving | ((o[:, a] >= 0) & (o[:, a] < size[a]))
        live &= t0 < t1
        x = o + t0[:, None] * d
        x = np.where(d < 0, np.ceil(x) - 1, np.floor(x))
        x = np.where(np.isfinite(x), x, 0)
        cell = np.clip(x, 0, size - 1).astype(np.int64)
        step = np.sign(d).astype(np.int64)
        delta = np.where(d != 0, 1 / np.abs(d), np.inf)
        t_max = np.where(d > 0, (cell + 1 - o) / d, np.where(d < 0, (cell - o) / d, np.inf))
    paths = [[] for _ in range(n)]
    active = np.flatnonzero(live)
    while len(active):
        c = cell[active]
        for k, (i, j) in zip(active.tolist(), c.tolist()):
            paths[k].append((i, j))
        tx, ty = t_max[active, 0], t_max[active, 1]
        go_x, go_y = tx <= ty, ty <= tx  # both at a vertex crossing
        t = np.where(go_x, tx, ty)
        cell[active, 0] += np.where(go_x, step[active, 0], 0)
        cell[active, 1] += np.where(go_y, step[active, 1], 0)
        t_max[active, 0] += np.where(go_x, delta[active, 0], 0)
        t_max[active, 1] += np.where(go_y, delta[active, 1], 0)
        c = cell[active]
        inside = (t < t1[active]) & (c[:, 0] >= 0) & (c[:, 0] < shape[0]) & \
                 (c[:, 1] >= 0) & (c[:, 1] < shape[1])
        active = active[inside]
    return [np.array(p, dtype=np.int64).reshape(-1, 2) for p in paths]


def register():
    """Register ``numpy_dda`` as a traversal plugin (not claimed exact: float64 DDA)."""
    return algos.register_traversal("numpy_dda", numpy_dda, exact=False,
                                    summary="cell DDA vectorised over rays in NumPy (examples/plugins)",
                                    citation="Amanatides & Woo 1987")
