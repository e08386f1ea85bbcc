"""Bit-identity pin: the first hits (t and cell) of every C intersector on fixed rays,
every surface, equal the outputs recorded before the kernels were tuned
(tests/hit_pin.py says how the pin was made)."""
import numpy as np
import pytest

from tests import hit_pin


@pytest.fixture(scope="module")
def pinned():
    with np.load(hit_pin.PIN) as data:
        return {k: data[k] for k in data.files}


@pytest.fixture(scope="module")
def current():
    return hit_pin.compute()


def test_the_pin_covers_every_kernel_and_surface(pinned):
    kernels = {k.split("/")[2] for k in pinned}
    surfaces = {k.split("/")[1] for k in pinned}
    assert kernels == set(hit_pin.KERNELS)
    assert surfaces == {"flat", "plane3", "triangles", "bilinear"}
    hits = sum(int(np.isfinite(v).sum()) for k, v in pinned.items() if k.endswith("/t"))
    misses = sum(int((~np.isfinite(v)).sum()) for k, v in pinned.items() if k.endswith("/t"))
    assert hits > 10000 and misses > 1000, (hits, misses)


@pytest.mark.parametrize("kernel", hit_pin.KERNELS)
def test_outputs_are_bit_identical_to_the_pin(kernel, pinned, current):
    keys = [k for k in pinned if k.split("/")[2] == kernel]
    assert keys
    for key in keys:
        want, got = pinned[key], current[key]
        if not np.array_equal(want.view(np.uint8), got.view(np.uint8)):
            bad = np.nonzero(np.any((want != got).reshape(len(want), -1), axis=1) |
                             (np.isnan(want) != np.isnan(got)).reshape(len(want), -1).any(axis=1)
                             if want.dtype.kind == "f" else
                             np.any(want != got, axis=1))[0]
            k = int(bad[0]) if len(bad) else -1
            raise AssertionError(
                f"{key}: {len(bad)} rays differ from the pin; first ray {k}: "
                f"pinned {want[k]!r}, got {got[k]!r}"
                + ("" if kernel in hit_pin.EXACT else
                   " (a float kernel: regenerate the pin only for a deliberate change)"))
