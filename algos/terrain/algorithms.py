"""The ways to compute each product, and how the default one is chosen."""
from __future__ import annotations

from dataclasses import dataclass

from .curvature import CURVATURE_REFUSED
from .directions import MAX_SNAP_DENOMINATOR, Direction

__all__ = ["TerrainAlgorithm", "HORIZON_ALGORITHMS", "VIEWSHED_ALGORITHMS", "PATTERN_MAX_DISTANCE"]

#: The default algorithm is "pattern" up to this max_distance (cells), measured.
PATTERN_MAX_DISTANCE = 384


@dataclass(frozen=True)
class TerrainAlgorithm:
    """One way to compute a terrain product.

    exact: agrees with the exact reference to rounding on every input it accepts.
    rational_only: needs every azimuth to snap to a rational slope.
    max_distance: accepts a finite max_distance.
    """

    name: str
    exact: bool
    rational_only: bool
    max_distance: bool
    summary: str
    citation: str = ""


HORIZON_ALGORITHMS: dict[str, TerrainAlgorithm] = {a.name: a for a in (
    TerrainAlgorithm("sweep", True, True, False,
                     "one sweep per line of a rational direction, upper convex hull",
                     "Dozier & Frew 1990"),
    TerrainAlgorithm("pattern", True, False, True,
                     "per-vertex walk over one shared breakpoint pattern per azimuth"),
    TerrainAlgorithm("rows", True, False, True,
                     "one shared breakpoint pattern per azimuth, a row of vertices at a time "
                     "(vectorised)"),
    TerrainAlgorithm("chain", True, False, True,
                     "per-vertex breakpoint walk that skips along max-trees of strips "
                     "parallel to the direction (one bound for every ray of a strip), started "
                     "from a lower bound borrowed from a vertex further along almost the same "
                     "line (continued-fraction convergents of the slope)", "Tevs et al. 2008"),
    TerrainAlgorithm("dda", True, False, True,
                     "per-vertex cell walk (Amanatides & Woo) over every breakpoint",
                     "Amanatides & Woo 1987"),
    TerrainAlgorithm("dda_maxmip", True, False, True,
                     "per-vertex cell walk that skips max-mipmap tiles below the horizon",
                     "Tevs et al. 2008"),
    TerrainAlgorithm("march", False, False, True,
                     "GRASS r.horizon-style fixed-step marcher (baseline)",
                     "Hofierka & Suri 2002 (r.horizon)"),
    TerrainAlgorithm("embree", False, False, True,
                     "HORAYZON-style: Embree occlusion rays, bisection over elevation (peer)",
                     "Steger et al. 2022 (HORAYZON)"),
)}

VIEWSHED_ALGORITHMS: dict[str, TerrainAlgorithm] = {a.name: a for a in (
    TerrainAlgorithm("dda", True, False, True, "line-of-sight cell walk per target"),
    TerrainAlgorithm("dda_maxmip", True, False, True,
                     "line-of-sight walk per target, skipping mipmap tiles below the segment"),
)}


def _auto_path(d: Direction, max_distance, curvature=False) -> str:
    """The default algorithm of one direction, by measurement (docs in :func:`horizon`):
    the sweep for a rational direction at unlimited distance; the row-vectorised pattern
    up to max_distance 384 cells; the chain walk otherwise (every other direction at
    unlimited distance, and longer radii). With curvature, whose peaks inside pieces
    neither the sweep, the rows nor the chain evaluate (:data:`CURVATURE_REFUSED`): the
    shared pattern up to 384 cells, the mipmap walk beyond."""
    if curvature:
        return "pattern" if max_distance is not None and max_distance <= PATTERN_MAX_DISTANCE \
            else "dda_maxmip"
    if max_distance is None and d.rational is not None:
        return "sweep"
    if max_distance is not None and max_distance <= PATTERN_MAX_DISTANCE:
        return "rows"
    return "chain"


def _pick_horizon_algorithm(algorithm, directions, max_distance, curvature=False):
    if curvature and algorithm in CURVATURE_REFUSED:
        raise ValueError(f"curvature: algorithm={algorithm!r} does not apply curvature "
                         f"({CURVATURE_REFUSED[algorithm]}); use 'pattern', 'dda', "
                         "'dda_maxmip' or 'auto'")
    if algorithm is None or algorithm == "auto":
        # curvature: the sweep's hull of breakpoints no longer holds (package docstring,
        # "Curvature"), so the exact per-vertex paths run
        # chosen by measurement (reports/terrain/targets.md, jacksboro 2048): the sweep
        # wherever it applies (157 ns per vertex against 4184 for dda_maxmip); else the
        # shared pattern up to max_distance 384 (431 against 1149 ns at 32 cells, 1569
        # against 2450 at 128, 4349 against 4068 at 512), the mipmap walk beyond
        if max_distance is None and all(d.rational is not None for d in directions) \
                and not curvature:
            return "sweep"
        return "pattern" if max_distance is not None and max_distance <= PATTERN_MAX_DISTANCE \
            else "dda_maxmip"
    if algorithm not in HORIZON_ALGORITHMS:
        raise ValueError(f"algorithm: expected one of {sorted(HORIZON_ALGORITHMS)} or 'auto', "
                         f"got {algorithm!r}")
    info = HORIZON_ALGORITHMS[algorithm]
    if info.rational_only:
        for k, d in enumerate(directions):
            if d.rational is None:
                raise ValueError(
                    f"azimuths[{k}]: {d.azimuth} is not a rational direction (slope p/q with "
                    f"q <= {MAX_SNAP_DENOMINATOR}); algorithm={algorithm!r} needs one "
                    f"(see algos.rational_azimuths)")
    if max_distance is not None and not info.max_distance:
        raise ValueError(f"max_distance: algorithm={algorithm!r} supports only unlimited distance")
    return algorithm
