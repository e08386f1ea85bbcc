"""A pinhole image of a height field with any intersector: ``algos.render``.

:func:`render` traces one primary ray per pixel (the camera of :mod:`algos.camera`) through
``algos.intersect`` and returns the image as arrays: the depth, the unit normal, the
intersector's per-ray statistics and a shaded RGB preview. :func:`shade` makes that
preview: terrain colour by height, a sun light (Lambert plus ambient) and, with
``fog > 0``, exponential height fog in closed form (the Hungarian lab's solution of
dL/ds = -sigma L + q with sigma(z) = sigma0 e^(b z), q = (q0/sigma0) sigma): along a
straight segment the optical depth is tau = sigma0 s (e^(b z1) - e^(b z0)) / (b (z1 - z0)),
and L = L_surface e^(-tau) + L_fog (1 - e^(-tau)).

Files (OpenEXR, PNG, the difference of two intersectors) are written by ``hftrace render``
(``bench/cli/render.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from . import plane_cameras
from .camera import check_camera, pinhole_frame, primary_directions
from .field import Field
from .intersect import intersect
from .lattice import MAX_ORIGIN
from .registry import get_intersector

__all__ = ["Rendering", "default_camera", "render", "shade", "PROJECTIONS"]


#: The cameras of :func:`render`: the pinhole, and the two whose image columns are
#: vertical planes (``algos.plane_cameras``).
PROJECTIONS = ("pinhole", "level", "orthographic")


@dataclass(frozen=True)
class Rendering:
    """One image of :func:`render`, row 0 at the top, ``(height, width)`` per pixel.

    Attributes
    ----------
    depth : float64 (height, width)
        Distance along the unit view ray to the first hit (cell units), ``inf`` on a miss.
    normal : float64 (height, width, 3)
        Unit surface normal at the hit, NaN on a miss.
    cells_visited, runs_visited : (height, width)
        The intersector's per-ray statistics (``algos.intersect`` outputs "stats"); zero
        for a rasteriser, which visits no cells per ray, and for a registered plugin
        (``algos.plugins``) or a BVH peer (``embree``, ``embree3``), which report none.
    points : float64 (height, width, 3)
        The hit points (the camera position on a miss).
    rgb : float64 (height, width, 3)
        The shaded preview in [0, 1] (:func:`shade`).
    elapsed_ns : int
        The intersector's (or rasteriser's) time for the whole image.
    cell : int32 (height, width, 2)
        ``(i, j)`` of the hit cell, ``(-1, -1)`` on a miss.
    """

    depth: np.ndarray
    normal: np.ndarray
    cells_visited: np.ndarray
    runs_visited: np.ndarray
    points: np.ndarray
    rgb: np.ndarray
    elapsed_ns: int
    cell: np.ndarray | None = None

    @property
    def t(self) -> np.ndarray:
        """The depth under its name in ``algos.raster.Image``, so that
        ``algos.raster.diff_images`` compares renderings of either kind."""
        return self.depth


def default_camera(heights):
    """(position, look_at) of the default view: above the north-west corner (low x, low
    y), looking at the field's centre at its mean height; float64 3-vectors, cell units."""
    rows, cols = heights.shape
    span = float(heights.max() - heights.min())
    centre = np.array([(cols - 1) / 2, (rows - 1) / 2, float(np.mean(heights))])
    position = np.array([-0.15 * cols, -0.15 * rows, float(heights.max()) + 0.15 * max(rows, cols) + span])
    return position, centre


def render(heights_or_field, algorithm="runs", *, surface="triangles", width=640, height=360,
           position=None, look_at=None, fov=60.0, fog=0.0, threads=None,
           projection="pinhole") -> Rendering:
    """Trace a pinhole image of a height field with one intersector.

    Parameters
    ----------
    heights_or_field : array (rows, cols) or HeightField
        What ``algos.intersect`` takes; a HeightField keeps its acceleration structures.
        The image is traced in cell units: a field's
        :attr:`~algos.HeightField.cell_heights` (heights in the pixel size's unit, as
        ``datasets_gen.load_file`` gives a DEM, divided by the square pixel size); an
        array is taken in cell units as it is.
    algorithm : str
        An intersector name (``algos.INTERSECTORS``), or a rasteriser of
        ``algos.raster.RASTERISERS`` (``zbuffer``, ``painter``, ``watkins``, ``warnock``,
        ``floating_horizon``: ``triangles`` only), which draws the same image from the
        same camera.
    surface : str
        One of ``algos.SURFACES``.
    width, height : int
        Image size in pixels.
    position, look_at : 3-vectors, optional
        Camera and target in grid coordinates (x = column, y = row, z = height, cell
        units); default :func:`default_camera`. Any viewing direction works: a vertical
        one (a nadir view) takes the frame of :mod:`algos.camera` (north, ``-y``, at the
        top of the image).
    fov : float
        Horizontal field of view in degrees, in (0, 180).
    fog : float
        Height-fog density sigma0 per cell at the lowest point (0: none), for ``rgb``;
        finite and >= 0.
    threads : int, optional
        As in ``algos.intersect`` (default every core); the image is bit-identical for
        every value.
    projection : str
        One of :data:`PROJECTIONS`: ``"pinhole"``, ``"level"`` (a level pinhole with a
        vertical lens shift that centres ``look_at``: every image column one vertical
        plane, ``algos.plane_cameras.level_camera_rays``) or ``"orthographic"`` (parallel
        rays from ``position`` to ``look_at``, the film ``2 |look_at - position|
        tan(fov / 2)`` cells wide, ``algos.plane_cameras.orthographic_rays``;
        ``depth`` is then measured from the vertical film through ``position``). The last
        two are the batches ``plane_maxmip`` traces a column at a time; a ``"pinhole"``
        image, whose rays share one eye, is the batch ``pitched_maxmip`` starts each
        walk near its hit for.

    Returns
    -------
    Rendering

    Raises
    ------
    ValueError
        An unknown algorithm, surface or projection, bad heights, a degenerate camera, a
        negative or non-finite fog, or (for the tracers) a camera whose rays would start
        beyond 2**30 cells (the message names the argument); a rasteriser with a
        projection other than ``"pinhole"``. A field with rectangular pixels or with voids
        (nodata) is refused before any camera is computed, the message naming the pixel
        size or the first void sample (fill voids with ``HeightField.filled``).
    TypeError
        A field holding a dask array (first hits need the heights in memory), or an
        image side that is not an integer.
    """
    field = heights_or_field if isinstance(heights_or_field, Field) else Field(heights_or_field)
    # cell units, as the kernels trace; refuses rectangular pixels and voids here, before
    # the default camera would be computed from metres or NaN
    heights = field.cell_heights
    cam, centre = default_camera(heights)
    # one check for every camera, naming the argument and its value
    position, look_at, fov, width, height = check_camera(
        position if position is not None else cam, look_at if look_at is not None else centre,
        fov, width, height)
    if isinstance(fog, bool) or not isinstance(fog, (int, float, np.integer, np.floating)) \
            or not (math.isfinite(fog) and fog >= 0):
        raise ValueError(f"fog: expected a density >= 0 per cell (0: none), got {fog!r}")
    from . import raster

    if projection not in PROJECTIONS:
        raise ValueError(f"projection: expected one of {', '.join(PROJECTIONS)}, "
                         f"got {projection!r}")
    tracing = algorithm not in raster.RASTERISERS
    if tracing and np.max(np.abs(position)) > MAX_ORIGIN:
        # the tracers' rays start at the eye: their origins' limit (algos.intersect)
        raise ValueError(f"position: {position.tolist()} lies beyond 2**30 cells, the limit "
                         "of a traced ray's origin; move the camera toward the field")
    if projection == "pinhole":
        frame, sx, sy = pinhole_frame(position, look_at, fov, width, height)
        directions = primary_directions(frame, sx, sy)
        origins = np.broadcast_to(frame[:3], directions.shape)
    elif projection == "level":
        origins, directions, _ = plane_cameras.level_camera_rays(position, look_at, fov,
                                                                 width, height)
    else:
        origins, directions = plane_cameras.orthographic_rays(position, look_at, fov, width,
                                                              height)
        reach = float(np.max(np.abs(origins)))
        if tracing and not reach <= MAX_ORIGIN:
            raise ValueError(f"fov: the orthographic film (2 |look_at - position| "
                             f"tan(fov / 2) cells wide) reaches a coordinate of {reach:.6g}, "
                             "beyond 2**30 cells, the limit of a traced ray's origin; narrow "
                             "fov or bring look_at closer")
    shape = (height, width)
    if algorithm in raster.RASTERISERS:
        if projection != "pinhole":
            raise ValueError(f"projection: the rasterisers draw 'pinhole' only, got "
                             f"{projection!r}")
        if surface != "triangles":
            raise ValueError(f"surface: the rasterisers draw 'triangles' only, got {surface!r}")
        image = raster.render(algorithm, field, position, look_at, fov, width, height,
                              threads=threads)
        t, normal, cell, elapsed = image.t.ravel(), image.normal, image.cell, image.elapsed_ns
        cells_visited = runs_visited = np.zeros(shape, dtype=np.int64)
    else:
        # a registered plugin or a BVH peer reports no per-ray statistics: its count
        # images are zero
        entry = get_intersector(algorithm)
        counted = entry.plugin is None and entry.kind != "peer"
        outputs = ("t", "cell", "normal") + (("stats",) if counted else ())
        hits = intersect(algorithm, field, origins, directions, surface=surface,
                         outputs=outputs, threads=threads)
        t, normal, cell, elapsed = hits.t, hits.normal, hits.cell, hits.elapsed_ns
        if hits.stats is None:
            cells_visited = runs_visited = np.zeros(shape, dtype=np.int64)
        else:
            cells_visited = hits.stats["cells_visited"].reshape(shape)
            runs_visited = hits.stats["runs_visited"].reshape(shape)
    # unit directions: t is a distance; the level camera's are not unit vectors, so its t
    # is in units of each ray's |d|
    depth = (t * np.linalg.norm(directions, axis=1) if projection == "level" else t).reshape(shape)
    normal = normal.reshape(height, width, 3)
    points = origins + np.where(np.isfinite(t), t, 0)[:, None] * directions
    points = points.reshape(height, width, 3)
    return Rendering(depth=depth, normal=normal, cells_visited=cells_visited,
                     runs_visited=runs_visited, points=points,
                     rgb=shade(depth, normal, points, position, heights, fog=fog),
                     elapsed_ns=int(elapsed), cell=np.asarray(cell).reshape(height, width, 2))


def shade(z, normal, points, position, heights, fog=0.0, fog_falloff=None, sun=(315.0, 35.0)):
    """RGB in [0, 1], shape ``depth.shape + (3,)``: terrain colour by height, Lambert sun
    (``sun`` = azimuth, elevation in degrees) plus ambient, height fog of density ``fog``
    (module docstring); a sky gradient where ``z`` (the depth) is not finite."""
    from matplotlib import colormaps

    hmin, hmax = float(heights.min()), float(heights.max())
    span = max(hmax - hmin, 1e-9)
    hit = np.isfinite(z)
    level = np.clip((points[..., 2] - hmin) / span, 0, 1)
    base = colormaps["terrain"](0.25 + 0.75 * level)[..., :3]
    az, alt = math.radians(sun[0]), math.radians(sun[1])
    light = np.array([math.sin(az) * math.cos(alt), math.cos(az) * math.cos(alt), math.sin(alt)])
    lambert = np.clip(np.nan_to_num(normal) @ light, 0, 1)
    colour = base * (0.25 + 0.75 * lambert[..., None])
    rows = z.shape[0]
    sky = np.linspace([0.55, 0.70, 0.90], [0.85, 0.90, 0.97], rows)[:, None, :]
    if fog > 0:
        b = fog_falloff if fog_falloff is not None else -3.0 / span
        z0 = position[2] - hmin
        z1 = points[..., 2] - hmin
        s = np.where(hit, z, 0.0)
        dz = z1 - z0
        with np.errstate(divide="ignore", invalid="ignore"):
            # optical depth of the segment; the limit sigma0 s e^(b z) where dz -> 0
            tau = np.where(np.abs(dz) > 1e-9,
                           fog * s * (np.exp(b * z1) - np.exp(b * z0)) / (b * dz),
                           fog * s * np.exp(b * z0))
        keep = np.exp(-np.clip(tau, 0, 50))[..., None]
        fog_colour = np.array([0.80, 0.84, 0.88])
        colour = colour * keep + fog_colour * (1 - keep)
    out = np.where(hit[..., None], colour, np.broadcast_to(sky, colour.shape))
    return np.clip(out, 0, 1)
