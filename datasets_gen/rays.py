"""Seeded ray sets for tests and benchmarks.

Every generator takes an explicit ``seed`` and uses ``numpy.random.Generator(PCG64)``,
so the same arguments give the same rays on any machine. Each returns a :class:`RaySet`
that records its parameters.

2D rays follow CONVENTIONS.md: ``origins`` and ``directions`` of shape ``(N, 2)``. With
``elevation`` given, rays are 3D ``(N, 3)``: the ``(x, y)`` direction scaled to unit
length and ``z = -tan(elevation)`` (looking down), origins at ``height`` above z = 0.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["RaySet", "by_run_length", "uniform", "lattice", "octant_directions",
           "mean_run_length"]


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


def by_run_length(r, n, shape, seed, *, jitter=0.0, origins="inside", elevation=None,
                  height=1.0):
    """Rays whose 8-connected mean run length is ``r``.

    The azimuth from the major axis is ``atan(1/r)`` (CONVENTIONS.md, "Mean run
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
    elevation, height : float, optional
        Degrees below the horizon and origin height, for 3D rays.
    """
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
                  jitter=jitter, origins=origins, elevation=elevation, height=height)
    if elevation is not None:
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
