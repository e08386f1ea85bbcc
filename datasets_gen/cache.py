"""The on-disk cache of generated fields and derived structures.

Entries are keyed by kind, name, parameters, seed and generator version (a SHA-256 of
their canonical JSON). Each entry is two files: ``<key>.npy`` (the array) and
``<key>.json`` (what it is, plus the SHA-256 of the array's bytes). Both are written to a
temporary file and renamed into place, data first, so a killed writer leaves either a
complete entry or none; an entry whose bytes do not match its recorded hash (or that
does not load) is treated as missing, deleted and rebuilt.

Location: the ``cache_dir`` argument, else ``$HFTRACE_CACHE``, else
``$XDG_CACHE_HOME/hftrace``, else ``~/.cache/hftrace``.
"""
from __future__ import annotations

import hashlib
import json
import os
import tempfile
import warnings
from typing import Callable

import numpy as np

__all__ = ["cache_dir", "entry_key", "cached_array", "CacheStats"]


class CacheStats:
    """Counters, for tests and reports: hits, misses (built) and rebuilt corrupt entries."""

    hits = 0
    misses = 0
    corrupt = 0


def cache_dir(override=None) -> str:
    if override:
        return os.fspath(override)
    if os.environ.get("HFTRACE_CACHE"):
        return os.environ["HFTRACE_CACHE"]
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(base, "hftrace")


def entry_key(description: dict) -> str:
    canonical = json.dumps(description, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()[:32]


#: entries at least this big are memory-mapped read-only instead of read into memory
MMAP_BYTES = 256 << 20


def _digest(array: np.ndarray) -> str:
    """SHA-256 of the C-order bytes, hashed in bands (no full-size copy)."""
    array = np.ascontiguousarray(array)
    digest = hashlib.sha256()
    flat = array.reshape(-1)
    step = 1 << 22
    for k in range(0, flat.size, step):
        digest.update(memoryview(np.ascontiguousarray(flat[k:k + step])).cast("B"))
    return digest.hexdigest()


def _atomic_write(path: str, write: Callable) -> None:
    directory = os.path.dirname(path)
    fd, tmp = tempfile.mkstemp(dir=directory, prefix=".tmp-", suffix=os.path.basename(path))
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise


def _read(directory: str, key: str):
    data_path = os.path.join(directory, key + ".npy")
    meta_path = os.path.join(directory, key + ".json")
    if not (os.path.exists(data_path) and os.path.exists(meta_path)):
        return None
    try:
        with open(meta_path) as f:
            meta = json.load(f)
        big = os.path.getsize(data_path) >= MMAP_BYTES
        array = np.load(data_path, allow_pickle=False, mmap_mode="r" if big else None)
        if _digest(array) != meta["sha256"]:
            raise ValueError("checksum mismatch")
        return array
    except Exception as exc:  # truncated, corrupt or foreign: rebuild
        CacheStats.corrupt += 1
        warnings.warn(f"hftrace cache: rebuilding corrupt entry {data_path} ({exc})",
                      RuntimeWarning, stacklevel=3)
        for p in (data_path, meta_path):
            if os.path.exists(p):
                os.unlink(p)
        return None


def cached_array(description: dict, build: Callable[[], np.ndarray], *, use_cache=True,
                 directory=None) -> np.ndarray:
    """The array ``build()`` makes for ``description``, from the cache when present."""
    if not use_cache:
        return build()
    directory = cache_dir(directory)
    os.makedirs(directory, exist_ok=True)
    key = entry_key(description)
    array = _read(directory, key)
    if array is not None:
        CacheStats.hits += 1
        return array
    CacheStats.misses += 1
    array = np.ascontiguousarray(build())
    _atomic_write(os.path.join(directory, key + ".npy"), lambda f: np.save(f, array))
    meta = dict(description=description, sha256=_digest(array), shape=list(array.shape),
                dtype=str(array.dtype))
    _atomic_write(os.path.join(directory, key + ".json"),
                  lambda f: f.write(json.dumps(meta, indent=1, default=str).encode()))
    return array
