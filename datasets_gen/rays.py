"""Seeded ray sets for tests and benchmarks.

Every generator takes an explicit ``seed`` and uses ``numpy.random.Generator(PCG64)``,
so the same arguments give the same rays on any machine. Each returns a :class:`RaySet`
that records its parameters.

2D rays follow docs/CONVENTIONS.md: ``origins`` and ``directions`` of shape ``(N, 2)``. With
``elevation`` given, rays are 3D ``(N, 3)``: the ``(x, y)`` direction scaled to unit
length and ``z = -tan(elevation)`` (looking down), origins at ``height`` above z = 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from algos.camera import pinhole_frame, primary_directions

__all__ = ["RaySet", "by_run_length", "uniform", "isotropic", "lattice", "octant_directions",
           "mean_run_length", "pinhole", "level_camera", "orthographic_camera", "parallel",
           "adversarial", "first_hit_hazards", "HAZARD_FAMILIES", "traversal_rays",
           "first_hit_rays", "coherent_rays", "orthographic_rays", "COHERENCE"]


@dataclass(frozen=True)
class RaySet:
    """Rays plus the parameters that made them."""

    origins: np.ndarray
    directions: np.ndarray
    params: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.origins)


def _rng(seed) -> np.random.Generator:
    if seed is None:
        raise ValueError("seed: every ray set is seeded; pass an integer")
    return np.random.Generator(np.random.PCG64(seed))


def octant_directions(alpha: np.ndarray, octant: np.ndarray) -> np.ndarray:
    """Directions ``(1, alpha)`` (slope ``alpha`` in [0, 1] to the major axis, so
    ``|minor/major|`` is exactly ``alpha`` and ``alpha = 1`` is an exact diagonal),
    mirrored into ``octant`` in 0..7 (bit 0: swap x/y, bit 1: negate x, bit 2: negate y).
    """
    alpha = np.asarray(alpha, dtype=np.float64)
    octant = np.asarray(octant)
    major, minor = np.ones_like(alpha), alpha
    swap = (octant & 1).astype(bool)
    dx = np.where(swap, minor, major)
    dy = np.where(swap, major, minor)
    dx = np.where(octant & 2, -dx, dx)
    dy = np.where(octant & 4, -dy, dy)
    return np.stack([dx, dy], axis=1) + 0.0


def _origins(rng, n, shape, where: str) -> np.ndarray:
    nx, ny = shape
    if where == "inside":
        return rng.uniform((0, 0), (nx, ny), size=(n, 2))
    if where == "around":
        # a margin of half the grid on every side: some rays enter, some miss
        return rng.uniform((-nx / 2, -ny / 2), (1.5 * nx, 1.5 * ny), size=(n, 2))
    raise ValueError(f"origins: expected 'inside' or 'around', got {where!r}")


def _lift(origins, directions, elevation, height):
    """Make 3D rays: unit (x, y) direction, descending at ``elevation`` degrees."""
    d2 = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    z = np.full((len(d2), 1), -math.tan(math.radians(elevation)))
    o3 = np.concatenate([origins, np.full((len(origins), 1), float(height))], axis=1)
    return o3, np.concatenate([d2, z], axis=1)


def _lift_range(origins, directions, elevation, height, seed):
    """Make 3D rays with unit directions, each descending at its own elevation drawn
    uniformly in degrees from ``elevation = (low, high)`` by a second stream
    (``PCG64(seed + 1)``), so the 2D rays are those of the same seed without it."""
    low, high = (float(v) for v in elevation)
    if not 0.0 <= low <= high <= 90.0:
        raise ValueError(f"elevation: expected degrees 0 <= low <= high <= 90, got {elevation}")
    n = len(origins)
    angle = np.radians(_rng(seed + 1).uniform(low, high, n))
    d2 = directions / np.linalg.norm(directions, axis=1, keepdims=True)
    d3 = np.column_stack([d2 * np.cos(angle)[:, None], -np.sin(angle)])
    o3 = np.column_stack([origins, np.full(n, float(height))])
    return o3, d3


def by_run_length(r, n, shape, seed, *, jitter=0.0, origins="inside", order="index",
                  elevation=None, height=1.0):
    """Rays whose 8-connected mean run length is ``r``.

    The azimuth from the major axis is ``atan(1/r)`` (docs/CONVENTIONS.md, "Mean run
    length"); rays are spread evenly over the 8 octants (octant ``k % 8`` for ray k).

    Parameters
    ----------
    r : float >= 1, or "random"
        Mean run length; ``"random"`` draws azimuths uniformly in [0, 2 pi).
    n : int
    shape : (nx, ny)
        Grid the origins are spread over.
    seed : int
    jitter : float
        Relative jitter of ``1/r`` (uniform in ``[-jitter, jitter]``).
    origins : {"inside", "around"}
    order : {"index", "octant"}
        ``"index"``: ray k in octant ``k % 8``. ``"octant"``: the same rays stably sorted
        by octant, so parallel rays are consecutive (the benchmarks' order).
    elevation : float or (low, high), optional
        Degrees below the horizon, for 3D rays. A float: every ray at that elevation,
        unit ``(x, y)`` and ``z = -tan(elevation)``. A pair: each ray at an elevation
        drawn uniformly from ``[low, high]`` by a second stream seeded ``seed + 1``, with
        unit 3D directions (the first-hit rays of :func:`first_hit_rays`).
    height : float
        Origin height of 3D rays (``z``, in cell units).

    Returns
    -------
    RaySet
        ``origins`` and ``directions`` float64 of shape ``(n, 2)``, or ``(n, 3)`` with
        ``elevation``.

    Raises
    ------
    ValueError
        ``r`` below 1, ``seed`` None, an unknown ``origins`` or ``order``, an elevation
        range outside ``0 <= low <= high <= 90``.
    """
    if order not in ("index", "octant"):
        raise ValueError(f"order: expected 'index' or 'octant', got {order!r}")
    rng = _rng(seed)
    n = int(n)
    if r == "random":
        phi = rng.uniform(0, 2 * math.pi, n)
        d = np.stack([np.cos(phi), np.sin(phi)], axis=1)
    else:
        r = float(r)
        if not r >= 1:
            raise ValueError(f"r: the mean run length must be >= 1, got {r}")
        alpha = np.full(n, 1.0 / r)
        if jitter:
            alpha = np.clip(alpha * (1 + rng.uniform(-jitter, jitter, n)), 0, 1)
        d = octant_directions(alpha, np.arange(n) % 8)
    o = _origins(rng, n, shape, origins)
    params = dict(kind="by_run_length", r=r, n=n, shape=tuple(shape), seed=seed,
                  jitter=jitter, origins=origins, order=order, elevation=elevation,
                  height=height)
    if order == "octant":
        by_octant = np.argsort(np.arange(n) % 8, kind="stable")
        o, d = o[by_octant], d[by_octant]
    if isinstance(elevation, (tuple, list)):
        o, d = _lift_range(o, d, elevation, height, seed)
    elif elevation is not None:
        o, d = _lift(o, d, elevation, height)
    return RaySet(o, d, params)


def uniform(n, shape, seed, *, origins="around", log_scale=(-3.0, 3.0)):
    """Arbitrary float64 rays: uniform origins, isotropic directions whose length is
    log-uniform over ``10**log_scale``, ``tmax`` left to the caller."""
    rng = _rng(seed)
    o = _origins(rng, int(n), shape, origins)
    phi = rng.uniform(0, 2 * math.pi, int(n))
    length = 10.0 ** rng.uniform(*log_scale, int(n))
    d = np.stack([np.cos(phi), np.sin(phi)], axis=1) * length[:, None]
    return RaySet(o, d, dict(kind="uniform", n=n, shape=tuple(shape), seed=seed,
                             origins=origins, log_scale=log_scale))


def isotropic(n, shape, seed, *, offset=0.0, snap=None):
    """Rays with unit directions at azimuths uniform in [0, 2 pi) and origins uniform over
    ``[offset, offset + nx) x [offset, offset + ny)``.

    With ``snap`` (e.g. ``2**-16``, the exact kernels' lattice) origins and directions
    are rounded to multiples of it, so the exact kernels take them without quantizing
    (the accuracy and stress studies; ``offset = 2**16`` gives long rays far from the
    origin). Returns a RaySet of float64 ``(n, 2)`` arrays.
    """
    rng = _rng(seed)
    n = int(n)
    o = offset + _origins(rng, n, shape, "inside")
    phi = rng.uniform(0, 2 * np.pi, n)
    d = np.stack([np.cos(phi), np.sin(phi)], 1)
    if snap is not None:
        o = np.round(o / snap) * snap
        d = np.round(d / snap) * snap
    return RaySet(o, d, dict(kind="isotropic", n=n, shape=tuple(shape), seed=seed,
                             offset=offset, snap=snap))


def lattice(n, shape, seed, *, origin_step=0.5, max_direction=4, direction_step=1.0):
    """Rays on a coarse dyadic lattice, where ties are the rule: origins are multiples
    of ``origin_step`` (including grid lines and corners), directions small multiples of
    ``direction_step`` (axis-parallel, diagonals, exact vertex hits)."""
    rng = _rng(seed)
    nx, ny = shape
    k = rng.integers((-2, -2), (int(nx / origin_step) + 3, int(ny / origin_step) + 3),
                     size=(int(n), 2))
    o = k * float(origin_step)
    d = rng.integers(-max_direction, max_direction + 1, size=(int(n), 2)) * float(direction_step)
    return RaySet(o.astype(np.float64), d.astype(np.float64),
                  dict(kind="lattice", n=n, shape=tuple(shape), seed=seed,
                       origin_step=origin_step, max_direction=max_direction,
                       direction_step=direction_step))


def mean_run_length(run_starts_per_ray) -> float:
    """Mean 8-connected run length over complete runs: for each ray, the distance
    between its first and last run starts divided by the number of runs between them."""
    total_cells = total_runs = 0
    for starts in run_starts_per_ray:
        starts = np.asarray(starts)
        if len(starts) >= 3:
            total_cells += abs(int(starts[-1]) - int(starts[1]))
            total_runs += len(starts) - 2
    return total_cells / total_runs if total_runs else float("nan")


def pinhole(position, look_at, fov, width, height, *, up=(0.0, 0.0, 1.0)):
    """Primary rays of a pinhole camera, one per pixel in row-major order (row 0 at the
    top of the image): origins all at ``position``, unit directions through the pixel
    centres. ``fov`` is the horizontal field of view in degrees. The camera is
    :func:`algos.camera.pinhole_frame`'s (the rasterisers' too); a vertical view with the
    default ``up`` takes its north-heading frame."""
    default_up = up is None or np.array_equal(np.asarray(up, dtype=np.float64), [0.0, 0.0, 1.0])
    frame, sx, sy = pinhole_frame(position, look_at, fov, int(width), int(height),
                                  up=None if default_up else up)
    d = primary_directions(frame, sx, sy)
    o = np.tile(frame[:3], (len(d), 1))
    up = (0.0, 0.0, 1.0) if up is None else up
    return RaySet(o, d, dict(kind="pinhole", position=frame[:3].tolist(),
                             look_at=list(map(float, look_at)), fov=fov, width=int(width),
                             height=int(height), up=list(map(float, up))))


def level_camera(position, look_at, fov, width, height):
    """Primary rays of a level pinhole camera with a vertical lens shift that centres
    ``look_at`` (``algos.plane_cameras.level_camera_rays``: every image column one
    vertical plane, directions not normalised), one per pixel in row-major order (row 0
    at the top), as a :class:`RaySet`. Raises ``ValueError`` as that function does."""
    from algos.plane_cameras import level_camera_rays

    o, d, shift = level_camera_rays(position, look_at, fov, width, height)
    return RaySet(o, d, dict(kind="level", position=list(map(float, position)),
                             look_at=list(map(float, look_at)), fov=fov, width=int(width),
                             height=int(height), shift=shift))


def orthographic_camera(position, look_at, fov, width, height):
    """Primary rays of an orthographic camera without roll
    (``algos.plane_cameras.orthographic_rays``: unit directions from ``position`` to
    ``look_at``, origins on the vertical film through ``position``, so every image
    column is one vertical plane), one per pixel in row-major order, as a
    :class:`RaySet`. Raises ``ValueError`` as that function does."""
    from algos.plane_cameras import orthographic_rays

    o, d = orthographic_rays(position, look_at, fov, width, height)
    return RaySet(o, d, dict(kind="orthographic", position=list(map(float, position)),
                             look_at=list(map(float, look_at)), fov=fov, width=int(width),
                             height=int(height)))


def parallel(n, shape, seed, *, direction=None, rational=None, octant=0, origins="inside",
             height=None, elevation=None):
    """``n`` parallel rays: one direction, many origins (orthographic cameras, sun and
    shadow rays, viewsheds), the batch ``runs_periodic`` is built for.

    Give either ``direction`` (a 2- or 3-vector) or ``rational=(p, q)``, ``0 <= p <= q``:
    the exact 2D direction ``(q, p)`` of slope p/q, mirrored into ``octant`` (see
    :func:`octant_directions`). ``height`` lifts the origins to 3D when the direction is
    2D (the 3D direction then gets z = 0, or with ``elevation``, degrees below the
    horizon, ``z = -|(dx, dy)| tan(elevation)``: the orthographic first-hit rays).
    """
    if elevation is not None and height is None:
        raise ValueError("elevation: needs height (the origins' z)")
    rng = _rng(seed)
    if (direction is None) == (rational is None):
        raise ValueError("direction, rational: give exactly one")
    if rational is not None:
        p, q = (int(v) for v in rational)
        if not 0 <= p <= q or q == 0:
            raise ValueError(f"rational: expected 0 <= p <= q, q > 0, got {rational}")
        d = octant_directions(np.array([p / q]), np.array([octant]))[0] * q
        d = np.round(d)  # exactly (+-q, +-p) or swapped
    else:
        d = np.asarray(direction, dtype=np.float64)
        if d.shape not in ((2,), (3,)) or not np.all(np.isfinite(d)):
            raise ValueError(f"direction: expected a finite 2- or 3-vector, got {direction}")
    o = _origins(rng, int(n), shape, origins)
    if height is not None:
        o = np.concatenate([o, np.full((len(o), 1), float(height))], axis=1)
        if d.shape == (2,):
            z = 0.0 if elevation is None else \
                -np.hypot(d[0], d[1]) * math.tan(math.radians(elevation))
            d = np.append(d, z)
    elif d.shape == (3,):
        o = np.concatenate([o, np.zeros((len(o), 1))], axis=1)
    return RaySet(o, np.tile(d, (len(o), 1)),
                  dict(kind="parallel", n=n, shape=tuple(shape), seed=seed,
                       direction=None if direction is None else list(map(float, direction)),
                       rational=rational, octant=octant, origins=origins, height=height,
                       elevation=elevation))


GOLDEN = (math.sqrt(5) - 1) / 2


def adversarial(shape, seed, n=64):
    """The 2D stress families, ``n`` rays each (where a family has that many), as a dict
    name -> RaySet. Every family targets a numerical hazard of a traversal:

    ``axis_parallel`` both signs along x and y, on cell centres and on grid lines;
    ``diagonals`` exact diagonals; ``through_vertices`` integer directions from vertices;
    ``origins_on_lines`` and ``origins_on_corners``; ``near_rational`` slopes p/q
    perturbed by 2^-40 (large denominators); ``golden`` and ``sqrt2`` slopes;
    ``vertical`` zero directions on integer points; ``first_run_clipped`` rays whose first
    run holds 0 or 1 cells (they start just before a row boundary).
    """
    rng = _rng(seed)
    nx, ny = shape
    n = int(n)
    octant = np.arange(n) % 8
    fam = {}

    def add(name, o, d, **extra):
        fam[name] = RaySet(np.asarray(o, np.float64), np.asarray(d, np.float64),
                           dict(kind="adversarial", family=name, shape=tuple(shape),
                                seed=seed, **extra))

    centres = rng.integers(0, (nx, ny), (n, 2)) + 0.5
    lines = rng.integers(0, (nx + 1, ny + 1), (n, 2)).astype(float)
    axis = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]], float)[np.arange(n) % 4]
    add("axis_parallel", np.where(np.arange(n)[:, None] % 2 == 0, centres, lines), axis)
    diag = np.array([[1, 1], [-1, 1], [1, -1], [-1, -1]], float)[np.arange(n) % 4]
    add("diagonals", lines, diag)
    add("through_vertices", lines,
        rng.integers(-5, 6, (n, 2)).astype(float) + (np.arange(n) % 2 == 0)[:, None] * [[1, 0]])
    on_line = rng.uniform(0, (nx, ny), (n, 2))
    on_line[np.arange(n) % 2 == 0, 0] = np.floor(on_line[np.arange(n) % 2 == 0, 0])
    on_line[np.arange(n) % 2 == 1, 1] = np.floor(on_line[np.arange(n) % 2 == 1, 1])
    phi = rng.uniform(0, 2 * math.pi, n)
    add("origins_on_lines", on_line, np.stack([np.cos(phi), np.sin(phi)], 1))
    add("origins_on_corners", lines, np.stack([np.cos(phi[::-1]), np.sin(phi[::-1])], 1))
    p = rng.integers(1, 50, n)
    q = p + rng.integers(1, 50, n)
    add("near_rational", centres, octant_directions(p / q + 2.0**-40, octant))
    add("golden", rng.uniform(0, (nx, ny), (n, 2)), octant_directions(np.full(n, GOLDEN), octant))
    add("sqrt2", rng.uniform(0, (nx, ny), (n, 2)),
        octant_directions(np.full(n, math.sqrt(2) - 1), octant))
    add("vertical", lines, np.zeros((n, 2)))
    # first run of 0 or 1 cells: slope alpha, start a hair (or one cell) below a row line
    alpha = rng.uniform(0.05, 1.0, n)
    start = rng.integers(0, (nx, ny), (n, 2)).astype(float)
    cells_before = np.arange(n) % 2  # 0 or 1 whole cells before the crossing
    start[:, 1] += 1.0 - alpha * (cells_before + 2.0**-10)  # above the 2^-16 lattice
    start[:, 1] = np.clip(start[:, 1], 0, ny)
    add("first_run_clipped", start, np.stack([np.ones(n), alpha], 1))
    return fam


#: The families of :func:`first_hit_hazards`, in the order their rays come
HAZARD_FAMILIES = ("grazing", "steep", "vertical", "start_low", "grid_aligned", "side_entry")


def first_hit_hazards(shape, seed, per_family=40, families=HAZARD_FAMILIES[:5]):
    """3D rays aimed at the first-hit kernels' hazards on a field of ``shape`` =
    ``(rows, cols)`` samples whose heights lie roughly in [0, 8] (cell units):

    ``grazing`` nearly horizontal (z slope in [-0.05, 0]), from inside and around the
    footprint; ``steep`` falling from 6-20; ``vertical`` straight down, half of them on
    grid vertices; ``start_low`` from z in [-3, 1] (often inside the solid), any
    direction; ``grid_aligned`` horizontal-ish along the axes, a diagonal and a 1:3 slope,
    half of them starting on grid lines; ``side_entry`` entering through the sides of the
    footprint below the rim, towards its centre.

    Every family is drawn, in the order of :data:`HAZARD_FAMILIES`, from one stream
    seeded ``seed``; ``families`` selects which are returned (in that order), so a
    subset's rays do not depend on the others. Returns a RaySet of float64 ``(n, 3)``
    arrays (directions not normalized), ``n = per_family * len(families)``, with
    ``params["family"]`` naming each ray's family.
    """
    unknown = [f for f in families if f not in HAZARD_FAMILIES]
    if unknown:
        raise ValueError(f"families: unknown family {unknown[0]!r}; valid: {', '.join(HAZARD_FAMILIES)}")
    rng = _rng(seed)
    rows, cols = shape
    k = int(per_family)
    uniform = rng.uniform
    normal = rng.normal
    o = {"grazing": np.column_stack([uniform(-5, cols + 5, k), uniform(-5, rows + 5, k),
                                     uniform(0, 8, k)]),
         "steep": np.column_stack([uniform(0, cols - 1, k), uniform(0, rows - 1, k),
                                   uniform(6, 20, k)])}
    d = {"grazing": np.column_stack([normal(size=k), normal(size=k), uniform(-0.05, 0.0, k)]),
         "steep": np.column_stack([normal(size=k) * 0.2, normal(size=k) * 0.2, -np.ones(k)])}
    xy = np.column_stack([uniform(0, cols - 1, k), uniform(0, rows - 1, k)])
    xy[: k // 2] = np.round(xy[: k // 2])  # on grid vertices
    o["vertical"] = np.column_stack([xy, uniform(-2, 20, k)])
    d["vertical"] = np.tile([0.0, 0.0, -1.0], (k, 1))
    o["start_low"] = np.column_stack([uniform(0, cols - 1, k), uniform(0, rows - 1, k),
                                      uniform(-3, 1, k)])
    d["start_low"] = np.column_stack([normal(size=k), normal(size=k), normal(size=k)])
    slope = np.array([[1.0, 0.0], [0.0, -1.0], [1.0, 1.0], [-3.0, 1.0]])[rng.integers(0, 4, k)]
    start = np.column_stack([rng.integers(0, cols - 1, k).astype(float),
                             rng.integers(0, rows - 1, k).astype(float)])
    start[::2] += uniform(0, 1, (len(start[::2]), 2))  # the others on grid lines
    o["grid_aligned"] = np.column_stack([start, uniform(0, 8, k)])
    d["grid_aligned"] = np.column_stack([slope, uniform(-0.2, 0.0, k)])
    side = rng.integers(0, 4, k)
    start = np.column_stack([uniform(0, cols - 1, k), uniform(0, rows - 1, k)])
    start[side == 0, 0] = -3
    start[side == 1, 0] = cols + 2
    start[side == 2, 1] = -3
    start[side == 3, 1] = rows + 2
    towards = np.array([(cols - 1) / 2, (rows - 1) / 2]) + normal(size=(k, 2)) * 5 - start
    o["side_entry"] = np.column_stack([start, uniform(-1, 9, k)])
    d["side_entry"] = np.column_stack([towards, uniform(-0.3, 0.1, k)
                                       * np.linalg.norm(towards, axis=1)])
    chosen = list(families)
    return RaySet(np.concatenate([o[f] for f in chosen]), np.concatenate([d[f] for f in chosen]),
                  dict(kind="first_hit_hazards", shape=tuple(shape), seed=seed, per_family=k,
                       families=tuple(chosen), family=np.repeat(chosen, k)))


# ---- the ray sets of the benchmark groups -----------------------------------------------
# what a sweep group, a study or a test traces: every measurement of one (run length,
# count, seed) traces the same rays, whichever module draws them

#: Ray batches of a first-hit group, from incoherent to coherent (docs/METHOD.md, "Cache
#: regimes and coherence"): "random" origins over the field at azimuth atan(1/r) in all
#: octants; "parallel" rays of one direction, slope 1/r (orthographic, sun shadows);
#: "camera" the pinhole rays of ``render``'s default camera (16:9, about ``rays`` pixels);
#: "level" and "orthographic" that view with ``render``'s level and orthographic
#: projections, whose image columns are vertical planes (the batches ``plane_maxmip``
#: traces a plane at a time).
COHERENCE = ("random", "parallel", "camera", "level", "orthographic")


def traversal_rays(shape, r, n, seed):
    """The 2D rays of a traversal group: :func:`by_run_length` with origins
    inside ``shape`` (nx, ny) and parallel rays consecutive; (origins, directions)."""
    rs = by_run_length(r, n, shape, seed, origins="inside", order="octant")
    return rs.origins, rs.directions


def first_hit_rays(field, r, n, seed):
    """First-hit rays: the traversal rays of ``field``'s grid, each falling at an elevation
    drawn from 5 to 20 degrees, from one cell above the field's highest point;
    (origins, directions) of shape (n, 3), unit directions."""
    rows, cols = field.heights.shape
    rs = by_run_length(r, n, (cols - 1, rows - 1), seed, origins="inside",
                               order="octant", elevation=(5.0, 20.0),
                               height=float(field.heights.max()) + 1.0)
    return rs.origins, rs.directions


def orthographic_rays(shape, r, n, seed, elevation_deg=10.0, top=None):
    """n parallel rays of octant slope 1/r (direction (r, 1) scaled), falling at
    elevation_deg, origins spread over the field one cell above ``top``:
    :func:`parallel`; (origins, directions) of shape (n, 3)."""
    rs = parallel(n, shape, seed, rational=(1, r), height=float(top) + 1.0,
                  elevation=elevation_deg)
    return rs.origins, rs.directions


def coherent_rays(field, coherence, r, n, seed):
    """First-hit rays (origins, directions), (N, 3), of one :data:`COHERENCE` kind:
    "random" is :func:`first_hit_rays`; "parallel" n orthographic rays of slope 1/r
    falling at 10 degrees; "camera" the pinhole rays of ``render``'s default camera, 16:9
    with about n pixels (``r`` unused); "level" and "orthographic" the same view and size
    through :func:`level_camera` and :func:`orthographic_camera`."""
    if coherence == "random":
        return first_hit_rays(field, r, n, seed)
    rows_, cols_ = field.heights.shape
    if coherence == "parallel":
        if r == "random":
            raise ValueError("coherence: parallel rays need a numeric run length, got 'random'")
        return orthographic_rays((cols_ - 1, rows_ - 1), int(round(float(r))), n, seed,
                                 top=field.hmax)
    if coherence in ("camera", "level", "orthographic"):
        from algos.render import default_camera

        width = max(2, int(round(math.sqrt(n * 16 / 9))))
        height = max(2, int(round(width * 9 / 16)))
        position, look_at = default_camera(field.heights)
        camera = {"camera": pinhole, "level": level_camera,
                  "orthographic": orthographic_camera}[coherence]
        rs = camera(position, look_at, 60.0, width, height)
        return rs.origins, rs.directions
    raise ValueError(f"coherence: expected one of {', '.join(COHERENCE)}, got {coherence!r}")
