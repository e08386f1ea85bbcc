"""What a terrain product call did: the paths that ran and their counts."""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["TerrainStats", "LAST_STATS"]


@dataclass
class TerrainStats:
    """What the last call did: C time, cells evaluated, tiles skipped, vertices resolved
    exactly (viewshed), per algorithm.

    ``algorithm``: the algorithms that ran, distinct, in azimuth order, joined by "+"
    ("sweep+chain"); ``paths``: the algorithm of each azimuth (horizon products).
    ``tile_tests``, ``bounded``: mipmap tiles tested, and vertices that started with a
    borrowed lower bound (``chain``). ``snapped_azimuths``, ``snap_max_change_deg``: the
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


#: Statistics of the most recent product call in this thread of control.
LAST_STATS = TerrainStats()
