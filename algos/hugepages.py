"""Large acceleration arrays on transparent huge pages.

A first-hit walk over a large field touches the heights, the cell maxima, the mipmap
levels and the compact tree at scattered places, so its misses in the translation
lookaside buffer grow with the field: one 4 KiB page per touched line. Backed by 2 MiB
pages, the same arrays need 512 times fewer translations. :func:`empty` allocates an
array of at least :data:`HUGE_PAGE` bytes in a private anonymous mapping, asks the kernel
for huge pages there (``madvise(MADV_HUGEPAGE)``) and starts the array on a 2 MiB
boundary, so every whole 2 MiB stretch of it can be one huge page. The contents, and so
every kernel's outputs, are unchanged: only where the bytes live differs.

Where the platform has no ``MADV_HUGEPAGE`` (macOS, Windows, Python without it), or the
array is smaller than a huge page, the arrays are ordinary NumPy allocations. Whether the
kernel grants the pages is its choice (``/sys/kernel/mm/transparent_hugepage/enabled``:
``always`` gives them anyway, ``madvise`` only to advised regions, ``never`` none).
"""
from __future__ import annotations

import mmap

import numpy as np

__all__ = ["HUGE_PAGE", "ADVICE", "empty", "adopt"]

#: The huge page size assumed for alignment (x86-64 and arm64 with 4 KiB base pages).
HUGE_PAGE = 2 << 20
#: ``mmap.MADV_HUGEPAGE`` where the platform has it, else None (plain allocations).
ADVICE = getattr(mmap, "MADV_HUGEPAGE", None)
_PRIVATE = getattr(mmap, "MAP_PRIVATE", None)
_ANONYMOUS = getattr(mmap, "MAP_ANONYMOUS", None)


def _huge_ok(nbytes: int) -> bool:
    return (ADVICE is not None and _PRIVATE is not None and _ANONYMOUS is not None
            and nbytes >= HUGE_PAGE)


def empty(shape, dtype, *, zero: bool = False) -> np.ndarray:
    """An uninitialised (``zero=True``: zero-filled) C-contiguous, writable array.

    Parameters
    ----------
    shape : int or tuple of int
    dtype : NumPy dtype
    zero : bool
        Fill with zeros (free for the huge-page path: a fresh mapping reads as zeros).

    Returns
    -------
    ndarray
        Of ``shape`` and ``dtype``. At least :data:`HUGE_PAGE` bytes and ``ADVICE``
        available: its data start on a 2 MiB boundary, inside a private anonymous mapping
        advised ``MADV_HUGEPAGE`` (the mapping lives as long as the array). Otherwise
        ``numpy.empty`` (``numpy.zeros``).
    """
    dtype = np.dtype(dtype)
    shape = (int(shape),) if np.ndim(shape) == 0 else tuple(int(s) for s in shape)
    nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
    if not _huge_ok(nbytes):
        return np.zeros(shape, dtype) if zero else np.empty(shape, dtype)
    # a private anonymous mapping (a shared one would be shmem, whose huge pages follow
    # another switch), one huge page longer so that the array can start aligned
    region = mmap.mmap(-1, nbytes + HUGE_PAGE, flags=_PRIVATE | _ANONYMOUS)
    try:
        region.madvise(ADVICE)
    except OSError:
        pass  # refused (huge pages disabled): base pages, as numpy.empty would give
    raw = np.frombuffer(region, dtype=np.uint8)
    start = (-raw.ctypes.data) % HUGE_PAGE
    return raw[start:start + nbytes].view(dtype).reshape(shape)


def adopt(array: np.ndarray, owner=None) -> np.ndarray:
    """``array`` moved onto huge pages (a copy from :func:`empty`) when it is at least
    :data:`HUGE_PAGE` bytes, ``ADVICE`` is available and it shares no memory with
    ``owner`` (the caller's array, which is never copied: it may be memory-mapped and
    larger than memory); else ``array`` itself."""
    if not _huge_ok(array.nbytes) or (owner is not None and np.may_share_memory(array, owner)):
        return array
    out = empty(array.shape, array.dtype)
    out[...] = array
    return out
