"""The lattice rounding: the NumPy twin equals the C rounding bit for bit."""
import numpy as np
from hypothesis import given
from hypothesis import strategies as st

import algos
from algos import _kernels

finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-2.0**30, max_value=2.0**30)
any_direction = st.floats(allow_nan=False, allow_infinity=False, min_value=-2.0**1000,
                          max_value=2.0**1000)


@given(ox=finite, oy=finite, dx=any_direction, dy=any_direction)
def test_numpy_twin_matches_c(ox, oy, dx, dy):
    (o,), (d,) = algos.quantize([(ox, oy)], [(dx, dy)])
    c = _kernels.quantize_ray(ox, oy, dx, dy)
    assert tuple(o) + tuple(d) == c
    for v in tuple(o) + tuple(d):
        assert not (v == 0 and np.signbit(v)), "-0.0 must become 0.0"


@given(ox=st.integers(-2**46, 2**46), oy=st.integers(-2**46, 2**46),
       dx=st.integers(-2**30, 2**30), dy=st.integers(-2**30, 2**30))
def test_lattice_rays_are_unchanged(ox, oy, dx, dy):
    """Origins and directions that are multiples of 2^-16 (|o| <= 2^30, |d| < 2^15) are
    left exactly as they are."""
    o = (ox / 65536, oy / 65536)
    d = (dx / 65536 * 2, dy / 65536 * 2) if max(abs(dx), abs(dy)) < 2**30 else (dx / 65536, dy / 65536)
    (qo,), (qd,) = algos.quantize([o], [d])
    assert tuple(qo) == o and tuple(qd) == d


def test_rounding_is_half_even_and_documented():
    (o,), (d,) = algos.quantize([(0.5 / 65536, 1.5 / 65536)], [(3.0, 1.0 + 2.0**-40)])
    assert tuple(o) == (0.0, 2 / 65536)
    # 31 significant bits in the larger component: 1 + 2^-40 keeps only its leading bit
    assert tuple(d) == (3.0, 1.0)
