"""The fixed-point lattice of the exact kernels.

An exact kernel first rounds the ray's ``(x, y)`` onto a lattice, then walks the rounded
ray exactly (docs/CONVENTIONS.md, "Exactness"):

* origin: each component is rounded to the nearest multiple of ``2**-16`` cell
  (ties to even);
* direction: scaled by the power of two ``2**s`` that puts ``max(|dx|, |dy|)`` in
  ``[2**30, 2**31)``, rounded to an integer (ties to even), and scaled back by
  ``2**-s``. A power-of-two scale changes no cell and, because the result is scaled
  back, leaves the meaning of ``t`` (and so of ``tmin``/``tmax``) unchanged.

So a ray whose components are multiples of ``2**-16`` with ``|o| <= 2**30`` and
``max |d| < 2**15`` is unchanged (directions are limited to ``|d| <= 2**1000``), and any
other direction keeps 31 significant bits in its larger component. ``-0.0`` becomes
``0.0``. :func:`quantize` is the NumPy twin of ``hf_quantize_ray`` in ``cext/walks/lattice.c``;
the tests check that they agree bit for bit.
"""
from __future__ import annotations

import numpy as np

FRAC_BITS = 16
#: Largest |origin component| accepted by every kernel, in cells.
MAX_ORIGIN = 2.0**30
#: Largest |direction component|: rounding may carry the larger component up by one
#: binade, which must stay finite.
MAX_DIRECTION = 2.0**1000
#: Largest grid side, in cells.
MAX_GRID_SIDE = 2**24
#: Bits kept in the larger direction component.
DIRECTION_BITS = 31

__all__ = ["quantize", "FRAC_BITS", "MAX_ORIGIN", "MAX_DIRECTION", "MAX_GRID_SIDE", "DIRECTION_BITS"]


def quantize(origins, directions):
    """Round rays onto the exact kernels' lattice.

    Parameters
    ----------
    origins, directions : array_like, shape (N, 2)
        Finite float rays, ``|origins| <= 2**30``.

    Returns
    -------
    origins, directions : ndarray of float64, shape (N, 2)
        The rounded rays; every value is exactly representable, and
        ``algos.traverse`` on an exact kernel equals ``reference_cells`` of these rays.
    """
    o = np.asarray(origins, dtype=np.float64).reshape(-1, 2)
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 2)
    o_q = np.rint(o * 2.0**FRAC_BITS) / 2.0**FRAC_BITS
    largest = np.max(np.abs(d), axis=1)
    _, exponent = np.frexp(largest)  # largest = m 2^e, m in [0.5, 1)
    scale = (DIRECTION_BITS - exponent)[:, None]
    d_q = np.ldexp(np.rint(np.ldexp(d, scale)), -scale)
    d_q[largest == 0] = 0.0
    return o_q + 0.0, d_q + 0.0  # + 0.0 turns -0.0 into 0.0
