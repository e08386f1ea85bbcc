"""What one terrain product call did: the paths that ran and their counts
(:class:`TerrainStats`), returned with the result when asked (``return_stats=True``),
never kept in module state, so calls on several threads (dask tiles) cannot mix them."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..field import is_dask

__all__ = ["TerrainStats"]


@dataclass
class TerrainStats:
    """What one call did: C time, cells evaluated, tiles skipped, vertices resolved
    exactly (viewshed), per algorithm.

    A product called with ``return_stats=True`` returns ``(result, stats)``; a DataArray
    result also carries ``algorithm``, ``paths`` and the snapping in its attrs.

    ``algorithm``: the algorithms that ran, distinct, in azimuth order, joined by "+"
    ("sweep+chain"); ``paths``: the algorithm of each azimuth (horizon products).
    ``ns``: nanoseconds in the C loops, summed over threads. ``cells``, ``skips``: cells
    evaluated and max-mipmap tiles skipped. ``exact_resolved``: viewshed vertices the
    float walk left uncertain, settled in rational arithmetic.
    ``tile_tests``, ``bounded``: mipmap tiles tested, and vertices that started with a
    borrowed lower bound (``chain``). For ``chain``, ``skips`` and ``tile_tests`` count the
    stretches of strip skipped and the strip bins tested, and ``cell_skips`` the cells
    stepped past by their highest corner. ``snapped_azimuths``, ``snap_max_change_deg``: the
    azimuths actually used and the largest move, in degrees, when snapping was asked for
    (``snap_denominator``); empty and 0.0 otherwise."""

    algorithm: str = ""
    ns: int = 0
    cells: int = 0
    skips: int = 0
    exact_resolved: int = 0
    paths: tuple = ()
    tile_tests: int = 0
    bounded: int = 0
    snapped_azimuths: tuple = ()
    snap_max_change_deg: float = 0.0
    cell_skips: int = 0

    def with_snap(self, snap) -> TerrainStats:
        """Record the snapping ``snap`` = (azimuths used, largest change in degrees) of
        :func:`~algos.terrain.azimuths.snap_azimuths` (nothing when None); returns self."""
        if snap is not None:
            self.snapped_azimuths = tuple(float(a) for a in snap[0])
            self.snap_max_change_deg = float(snap[1])
        return self


def check_return_stats(return_stats, heights) -> None:
    """Validate a product's ``return_stats`` flag for the input ``heights``."""
    if not isinstance(return_stats, (bool, np.bool_)):
        raise TypeError(f"return_stats: expected a bool, got {return_stats!r}")
    if return_stats and is_dask(heights):
        raise ValueError("return_stats: a lazy (dask) result is computed tile by tile, each "
                         "tile with its own statistics, so there are none to return; compute "
                         "it in memory for them (a DataArray result records the snapping in "
                         "its attrs)")


def returned(result, stats: TerrainStats, return_stats) -> object:
    """What a product returns: ``(result, stats)`` when asked for, else the result."""
    return (result, stats) if return_stats else result


def with_stats(product, heights, *args, **kwargs):
    """``(result, stats)`` of ``product(heights, *args, **kwargs)``; stats is None for a
    lazy (dask) result, whose statistics are per tile."""
    if is_dask(heights):
        return product(heights, *args, **kwargs), None
    return product(heights, *args, return_stats=True, **kwargs)
