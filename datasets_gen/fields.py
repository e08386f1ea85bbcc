"""Seeded synthetic height fields.

Every generator returns a float32 array ``H`` of shape ``(rows, cols)`` (``H[j, i]`` is
the height at grid point ``(x=i, y=j)``, docs/CONVENTIONS.md) in cell units: one unit of
height is one cell's width.

Determinism: the same name, parameters and seed give identical bytes on any machine
and NumPy version. To that end the generators use only IEEE-754 basic arithmetic
(+, -, *, /, floor), which every platform rounds the same way: random numbers come from
the raw 64-bit output of PCG64 (a stable bit stream) turned into doubles by hand, noise
gradients come from an integer hash, sine is a fixed polynomial (:func:`det_sin`), and
every sum runs in a fixed order (no pairwise or SIMD reductions). Values are computed in
float64 and rounded once to float32.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

__all__ = ["GENERATORS", "Generator", "generate", "det_sin", "det_cos", "MIN_SIDE",
           "MAX_SIDE"]

MIN_SIDE = 2
MAX_SIDE = 32768
#: samples per band of the banded generators (float64 temporaries of 1 MiB)
BAND_SAMPLES = 1 << 17
_TWO_PI = 6.283185307179586
_PI = 3.141592653589793
_HALF_PI = 1.5707963267948966


# ---- deterministic building blocks ------------------------------------------------------
def det_sin(x):
    """sin(x) from basic arithmetic only (reduction to [-pi/2, pi/2], odd Taylor series to
    x^23): |error| < 1e-15 for |x| < 1e6, and bit-identical on every platform."""
    x = np.asarray(x, dtype=np.float64)
    k = np.floor(x / _TWO_PI + 0.5)
    r = x - k * _TWO_PI  # in [-pi, pi]
    r = np.where(r > _HALF_PI, _PI - r, r)
    r = np.where(r < -_HALF_PI, -_PI - r, r)
    r2 = r * r
    # Horner form of r - r^3/3! + r^5/5! - ... + r^23/23!
    acc = np.zeros_like(r)
    for n in range(23, 1, -2):
        acc = (acc + (1.0 if (n // 2) % 2 == 0 else -1.0) / math.factorial(n)) * r2
    return r + r * acc


def det_cos(x):
    """cos(x) = sin(x + pi/2), deterministic like :func:`det_sin`."""
    return det_sin(np.asarray(x, dtype=np.float64) + _HALF_PI)


def _hash(*keys):
    """A 64-bit integer hash (SplitMix64 finaliser chain) of integer arrays, wrapping."""
    h = np.uint64(0x9E3779B97F4A7C15)
    with np.errstate(over="ignore"):
        for key in keys:
            h = h ^ np.asarray(key).astype(np.uint64)
            h = (h ^ (h >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
            h = (h ^ (h >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
            h = h ^ (h >> np.uint64(31))
    return h


def _unit(bits):
    """Doubles in [0, 1) from uint64 bits: the top 53 bits times 2^-53 (exact)."""
    return (np.asarray(bits, dtype=np.uint64) >> np.uint64(11)).astype(np.float64) * 2.0**-53


def _uniform(seed, n):
    """n doubles in [0, 1) from PCG64's raw stream (stable across NumPy versions)."""
    bits = np.random.PCG64(seed).random_raw(int(n))
    return _unit(bits)


def _gradient_noise(rows, cols, frequency, seed, octave, row0=0):
    """2D gradient noise (Perlin-style, quintic fade, hashed gradients in [-1, 1]^2) at
    grid points scaled by ``frequency``; values roughly in [-1, 1]. Rows ``row0`` to
    ``row0 + rows - 1`` of the field (each value depends on its own point only, so a
    field computed in bands has the same bytes)."""
    x = np.arange(cols, dtype=np.float64) * frequency
    y = np.arange(row0, row0 + rows, dtype=np.float64) * frequency
    ix = np.floor(x).astype(np.int64)
    iy = np.floor(y).astype(np.int64)
    fx, fy = x - ix, y - iy
    ux = fx * fx * fx * (fx * (fx * 6.0 - 15.0) + 10.0)
    uy = fy * fy * fy * (fy * (fy * 6.0 - 15.0) + 10.0)
    # gradient tables on the lattice points the grid touches
    lx = np.arange(ix[0], ix[-1] + 2)
    ly = np.arange(iy[0], iy[-1] + 2)
    h = _hash(seed, octave, ly[:, None] + 0 * lx[None, :], lx[None, :] + 0 * ly[:, None])
    gx = _unit(h) * 2.0 - 1.0
    gy = _unit(_hash(h)) * 2.0 - 1.0
    cx, cy = ix - ix[0], iy - iy[0]

    def corner(dj, di, ox, oy):
        # gather rows, then columns: two 1D gathers, far cheaper than one 2D fancy index
        gxc = np.take(gx[cy + dj], cx + di, axis=1)
        gyc = np.take(gy[cy + dj], cx + di, axis=1)
        gxc *= (fx - ox)[None, :]
        gyc *= (fy - oy)[:, None]
        gxc += gyc
        return gxc

    d00 = corner(0, 0, 0.0, 0.0)
    d10 = corner(0, 1, 1.0, 0.0)
    d01 = corner(1, 0, 0.0, 1.0)
    d11 = corner(1, 1, 1.0, 1.0)
    d10 -= d00
    d10 *= ux[None, :]
    d10 += d00  # top edge
    d11 -= d01
    d11 *= ux[None, :]
    d11 += d01  # bottom edge
    d11 -= d10
    d11 *= uy[:, None]
    d11 += d10
    return d11


def _fbm_sum(rows, cols, seed, scale, octaves, lacunarity, gain, ridged=False, row0=0):
    total = np.zeros((rows, cols))
    amplitude, frequency, norm = 1.0, 1.0 / scale, 0.0
    weight = np.ones((rows, cols)) if ridged else None
    for octave in range(int(octaves)):
        n = _gradient_noise(rows, cols, frequency, seed, octave, row0)
        if ridged:
            # ridged multifractal (Musgrave): sharp crests where the noise crosses zero,
            # each octave weighted by the previous one
            n = 1.0 - np.abs(n)
            n = n * n * weight
            weight = np.clip(n * 2.0, 0.0, 1.0)
        total += amplitude * n
        norm += amplitude
        amplitude *= gain
        frequency *= lacunarity
    return total / norm


# ---- the generators -------------------------------------------------------------------
def flat(rows, cols, seed=0, height=0.0):
    """A constant field: every height equal (culling's best case, the most ties)."""
    return np.full((rows, cols), float(height))


def tilted_plane(rows, cols, seed=0, slope_x=0.25, slope_y=0.125, height=0.0):
    """``height + slope_x x + slope_y y``."""
    return height + slope_x * np.arange(cols)[None, :] + slope_y * np.arange(rows)[:, None]


def spike(rows, cols, seed=0, height=None, radius=None, x=None, y=None):
    """A single smooth peak ``height (1 - (r/radius)^2)^3`` at ``(x, y)`` (default: the
    centre, height and radius a quarter of the smaller side), zero elsewhere."""
    side = min(rows, cols)
    height = side / 4 if height is None else float(height)
    radius = max(side / 4, 1.0) if radius is None else float(radius)
    x = (cols - 1) / 2 if x is None else float(x)
    y = (rows - 1) / 2 if y is None else float(y)
    q = ((np.arange(cols)[None, :] - x) ** 2 + (np.arange(rows)[:, None] - y) ** 2) / radius**2
    bump = np.clip(1.0 - q, 0.0, None)
    return height * bump * bump * bump


def ridges(rows, cols, seed=0, wavelength=32.0, angle=30.0, amplitude=4.0):
    """Oriented sinusoidal ridges: ``amplitude sin(2 pi (x cos a + y sin a) / wavelength)``
    with ``a`` in degrees."""
    a = angle * _PI / 180.0
    ca, sa = float(det_cos(a)), float(det_sin(a))
    phase = (np.arange(cols)[None, :] * ca + np.arange(rows)[:, None] * sa) * (_TWO_PI / wavelength)
    return amplitude * det_sin(phase)


def fbm(rows, cols, seed=0, scale=128.0, octaves=6, lacunarity=2.0, gain=0.5,
        amplitude=64.0, *, band=None):
    """Fractional Brownian motion: ``octaves`` of gradient noise, the first with lattice
    spacing ``scale`` cells, each next one ``lacunarity`` times finer and ``gain`` times
    weaker; normalised, then scaled to about ``[-amplitude, amplitude]``."""
    row0, row1 = band or (0, rows)
    return amplitude * _fbm_sum(row1 - row0, cols, seed, scale, octaves, lacunarity, gain,
                                row0=row0)


def ridged(rows, cols, seed=0, scale=128.0, octaves=6, lacunarity=2.0, gain=0.5,
           amplitude=64.0, *, band=None):
    """Ridged multifractal: sharp crests from ``1 - |noise|``, heights in ``[0, amplitude]``."""
    row0, row1 = band or (0, rows)
    return amplitude * _fbm_sum(row1 - row0, cols, seed, scale, octaves, lacunarity, gain,
                                ridged=True, row0=row0)


def diamond_square(rows, cols, seed=0, roughness=0.5, amplitude=64.0):
    """The diamond-square midpoint displacement on the smallest 2^k + 1 square that
    covers the grid, cropped; displacement halves by ``roughness`` per level."""
    side = 1
    while side + 1 < max(rows, cols):
        side *= 2
    n = side + 1
    h = np.zeros((n, n))
    stream = np.random.PCG64(seed)

    def draws(count):
        """The next `count` values in [-1, 1) of one raw PCG64 stream."""
        return _unit(stream.random_raw(int(count))) * 2.0 - 1.0

    corners = draws(4) * amplitude
    h[0, 0], h[0, side], h[side, 0], h[side, side] = corners
    step, scale = side, amplitude * roughness
    while step > 1:
        half = step // 2
        # diamond step: centres of squares
        centres = h[:-1:step, :-1:step] + h[:-1:step, step::step] + h[step::step, :-1:step] + h[step::step, step::step]
        noise = draws(centres.size).reshape(centres.shape)
        h[half::step, half::step] = centres / 4.0 + noise * scale
        # square step: edge midpoints, averaging the 3 or 4 neighbours present
        for j0 in (0, half):
            i0 = half if j0 == 0 else 0
            jj, ii = np.meshgrid(np.arange(j0, n, step), np.arange(i0, n, step), indexing="ij")
            acc = np.zeros(jj.shape)
            cnt = np.zeros(jj.shape)
            for dj, di in ((-half, 0), (half, 0), (0, -half), (0, half)):
                nj, ni = jj + dj, ii + di
                ok = (nj >= 0) & (nj < n) & (ni >= 0) & (ni < n)
                acc = acc + np.where(ok, h[np.clip(nj, 0, n - 1), np.clip(ni, 0, n - 1)], 0.0)
                cnt = cnt + ok
            noise = draws(jj.size).reshape(jj.shape)
            h[jj, ii] = acc / cnt + noise * scale
        step, scale = half, scale * roughness
    return h[:rows, :cols]


def terraces(rows, cols, seed=0, levels=8, scale=128.0, octaves=5, amplitude=64.0, *,
             band=None):
    """Quantised fBm: ``levels`` flat steps, so many neighbouring heights are equal."""
    row0, row1 = band or (0, rows)
    base = _fbm_sum(row1 - row0, cols, seed, scale, octaves, 2.0, 0.5, row0=row0)  # about [-1, 1]
    return amplitude * np.floor((base + 1.0) * 0.5 * levels) / levels


def uniform(rows, cols, seed=0, low=0.0, high=64.0):
    """I.i.d. heights uniform in ``[low, high)``: no coherence, culling's worst case."""
    return low + (high - low) * _uniform(seed, rows * cols).reshape(rows, cols)


def canyon(rows, cols, seed=0, depth=48.0, width=None, meander=None, wavelength=None,
           roughness=8.0):
    """A plateau cut by one meandering canyon along x: the floor ``depth`` below the rim,
    smooth walls over ``width`` cells, rough rims from fBm."""
    width = max(rows / 8, 2.0) if width is None else float(width)
    meander = rows / 6 if meander is None else float(meander)
    wavelength = max(cols / 2, 4.0) if wavelength is None else float(wavelength)
    centre = (rows - 1) / 2 + meander * det_sin(np.arange(cols) * (_TWO_PI / wavelength))
    distance = np.abs(np.arange(rows)[:, None] - centre[None, :]) / width
    q = np.clip(1.0 - distance * distance, 0.0, None)
    carve = depth * q * q
    noise = _fbm_sum(rows, cols, seed, max(min(rows, cols) / 4, 2.0), 4, 2.0, 0.5)
    return depth + roughness * noise - carve


# the three 32-bit seeds of the Hungarian lab's noise
_SINES16_SEEDS = (0x1D4E1D4E, 0x58F958F9, 0x129F129F)


def sines16_frequencies():
    """The 16 wave vectors s_k of the Hungarian seed's noise: for k = 0..15 each seed's
    low 16 bits / 65536 - 0.5, then every seed shifted right by one."""
    s = list(_SINES16_SEEDS)
    out = []
    for _ in range(16):
        out.append(tuple((v & 0xFFFF) / 65536.0 - 0.5 for v in s))
        s = [v >> 1 for v in s]
    return out


def sines16(rows, cols, seed=0, frequency=0.5, amplitude=16.0):
    """The Hungarian seed's noise ``sum_k sin(s_k . r) / 32 + 0.5`` (a 3D function),
    sampled on the plane ``r = frequency (x, 0, y)`` and scaled by ``amplitude``."""
    x = np.arange(cols, dtype=np.float64)[None, :] * frequency
    y = np.arange(rows, dtype=np.float64)[:, None] * frequency
    total = np.zeros((rows, cols))
    for sx, _sy, sz in sines16_frequencies():
        total = total + det_sin(sx * x + sz * y)
    return amplitude * (total / 32.0 + 0.5)


@dataclass(frozen=True)
class Generator:
    """A named generator with its documented defaults."""

    name: str
    function: Callable
    summary: str
    defaults: dict = field(default_factory=dict)
    version: int = 1  # bump when the output for given parameters changes


def first_sentence(doc) -> str:
    """The first sentence of a docstring's first paragraph, on one line (a summary that
    stops at a line break would cut it mid-sentence)."""
    import re

    paragraph = " ".join((doc or "").strip().split("\n\n")[0].split())
    # a sentence ends at a full stop followed by a capital letter or by the end ("I.i.d. heights")
    match = re.match(r"(.+?\.)(?=\s+[A-Z]|$)", paragraph)
    return match.group(1) if match else paragraph


def _defaults(function):
    import inspect

    return {k: v.default for k, v in inspect.signature(function).parameters.items()
            if k not in ("rows", "cols", "seed", "band")}


def _banded(function) -> bool:
    """Whether the generator computes any band of rows on its own (``band=(row0, row1)``),
    each value from its own point only: then bands run on every core, same bytes."""
    import inspect

    return "band" in inspect.signature(function).parameters


GENERATORS: dict[str, Generator] = {
    f.__name__: Generator(f.__name__, f, first_sentence(f.__doc__), _defaults(f))
    for f in (flat, tilted_plane, spike, ridges, fbm, ridged, diamond_square, terraces,
              uniform, canyon, sines16)
}


# parameter constraints: name -> (test, what it must be)
_POSITIVE = (lambda v: v > 0, "a positive number")
_CONSTRAINTS = {
    "octaves": (lambda v: float(v).is_integer() and 1 <= v <= 16, "an integer in [1, 16]"),
    "levels": (lambda v: float(v).is_integer() and v >= 1, "an integer >= 1"),
    "scale": _POSITIVE, "wavelength": _POSITIVE, "lacunarity": _POSITIVE,
    "radius": _POSITIVE, "width": _POSITIVE, "frequency": _POSITIVE,
    "gain": (lambda v: 0 < v <= 1, "a number in (0, 1]"),
    "roughness": (lambda v: v >= 0, "a number >= 0"),
}


def _check_params(name, params):
    for key, value in params.items():
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise TypeError(f"{key}: expected a number, got {value!r}")
        if not math.isfinite(value):
            raise ValueError(f"{key}: expected a finite number, got {value!r}")
        test, what = _CONSTRAINTS.get(key, (lambda v: True, ""))
        if not test(value):
            raise ValueError(f"{key}: {name} needs {what}, got {value!r}")
    if name == "uniform" and not params.get("low", 0.0) < params.get("high", 64.0):
        raise ValueError("low, high: uniform needs low < high")


def generate(name, size=256, seed=0, threads=None, **params) -> np.ndarray:
    """Height field ``name`` of ``size`` (int or ``(rows, cols)``), float32.

    The noise generators (fbm, ridged, terraces) compute bands of rows on ``threads``
    threads (default every core); the bytes do not depend on it.

    Raises ValueError naming the parameter for unknown names, sizes outside
    ``[2, MAX_SIDE]`` or parameters the generator does not take.
    """
    if name not in GENERATORS:
        raise ValueError(f"name: unknown generator {name!r}; valid names are "
                         f"{', '.join(GENERATORS)}")
    scalar = np.ndim(size) == 0
    rows, cols = (size, size) if scalar else tuple(size)
    for label, side in zip(("size", "size") if scalar else ("size[0]", "size[1]"), (rows, cols)):
        if isinstance(side, bool) or not isinstance(side, (int, np.integer)):
            raise TypeError(f"size: {label} must be an integer, got {side!r}")
        if not MIN_SIDE <= side <= MAX_SIDE:
            raise ValueError(f"size: {label} = {side} outside [{MIN_SIDE}, {MAX_SIDE}]")
    gen = GENERATORS[name]
    unknown = set(params) - set(gen.defaults)
    if unknown:
        raise ValueError(f"{sorted(unknown)[0]}: not a parameter of {name}; it takes "
                         f"{', '.join(gen.defaults) or 'no parameters'}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed: expected a non-negative integer, got {seed!r}")
    _check_params(name, params)
    rows, cols, seed = int(rows), int(cols), int(seed)
    if _banded(gen.function) and rows * cols >= 2 * BAND_SAMPLES:
        return _generate_bands(gen.function, rows, cols, seed, params, threads)
    heights = np.asarray(gen.function(rows, cols, seed, **params), dtype=np.float64)
    heights = np.broadcast_to(heights, (rows, cols))
    return np.ascontiguousarray(heights, dtype=np.float32)


def _generate_bands(function, rows, cols, seed, params, threads):
    """Bands of about ``BAND_SAMPLES`` samples (float64 temporaries that stay in cache),
    computed on a thread pool (NumPy releases the GIL in its loops) straight into the
    float32 result; the bytes are those of one whole-field call (tested)."""
    from algos.parallel import resolve_threads, run_ranges

    out = np.empty((rows, cols), dtype=np.float32)
    band_rows = max(1, BAND_SAMPLES // cols)
    n_bands = -(-rows // band_rows)

    def work(a, b):
        for k in range(a, b):
            r0, r1 = k * band_rows, min(rows, (k + 1) * band_rows)
            out[r0:r1] = function(rows, cols, seed, band=(r0, r1), **params)

    run_ranges(n_bands, resolve_threads(threads), work, chunks_per_thread=4, min_chunk=1)
    return out
