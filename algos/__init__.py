"""hftrace's public API: exact references, the algorithm registry and the C kernels.

>>> import algos
>>> algos.reference_cells((0.5, 0.5), (2, 3), (4, 4))
[(0, 0), (0, 1), (1, 1), (1, 2), (2, 2), (2, 3)]

See docs/CONVENTIONS.md for the grid, the cell rules and the API.
"""
from . import plugins, raster
from . import registry as _registry
from .brute import brute_force_hits
from .field import Field, HeightField, as_field
from .georef import IUGG_MEAN_EARTH_RADIUS_M, WGS84_SEMI_MAJOR_AXIS_M
from .intersect import HIT_OUTPUTS, STATS, Hits, intersect
from .lattice import quantize
from .plugins import register_intersector, register_traversal
from .raster import RASTERISERS
from .reference import major_axis, reference_cells, reference_runs, runs_from_cells
from .registry import (
    INTERSECTOR_REGISTRY,
    SURFACES,
    TRAVERSAL_REGISTRY,
    Intersector,
    Traversal,
    get_intersector,
    get_traversal,
)
from .render import Rendering, render
from .terrain import (
    DEFAULT_REFRACTION,
    HORIZON_ALGORITHMS,
    VIEWSHED_ALGORITHMS,
    horizon,
    openness,
    rational_azimuths,
    shadows,
    sky_view_factor,
    viewshed,
)
from .traverse import (
    DEFAULT_MAX_DENOMINATOR,
    OUTPUTS,
    WORKLOADS,
    CellPaths,
    PathCounts,
    RunPaths,
    prepare_timed,
    traverse,
    walk_timed,
)

__all__ = [
    "TRAVERSALS", "TRAVERSAL_REGISTRY", "Traversal", "get_traversal",
    "reference_cells", "reference_runs", "runs_from_cells", "major_axis", "quantize",
    "traverse", "walk_timed", "prepare_timed", "CellPaths", "RunPaths", "PathCounts",
    "DEFAULT_MAX_DENOMINATOR", "OUTPUTS", "WORKLOADS",
    "INTERSECTORS", "INTERSECTOR_REGISTRY", "Intersector", "get_intersector", "SURFACES",
    "intersect", "Hits", "HIT_OUTPUTS", "STATS", "Field", "HeightField", "as_field",
    "brute_force_hits", "WGS84_SEMI_MAJOR_AXIS_M", "IUGG_MEAN_EARTH_RADIUS_M",
    "DEFAULT_REFRACTION", "render", "Rendering", "raster", "RASTERISERS",
    "horizon", "shadows", "sky_view_factor", "openness", "viewshed", "rational_azimuths",
    "HORIZON_ALGORITHMS", "VIEWSHED_ALGORITHMS", "register_intersector", "register_traversal",
    "plugins",
]


def __getattr__(name):
    """``TRAVERSALS`` and ``INTERSECTORS``, read from the registry at each access, so a
    kernel registered later (``algos.plugins``) is listed."""
    if name in ("TRAVERSALS", "INTERSECTORS"):
        return getattr(_registry, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
