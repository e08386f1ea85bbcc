"""The pinhole camera: one home for the frame that the tracers' primary rays
(``datasets_gen.rays.pinhole``, :func:`algos.render`) and the rasterisers
(:mod:`algos.raster`) share, so that every renderer sees the same pixels.

A camera at ``position`` looks at ``look_at``; ``fov`` is the horizontal field of view in
degrees. The frame is ``forward`` (unit, towards ``look_at``), ``right = forward x up``
normalised and ``true_up = right x forward``, with ``up = +z`` unless given: the camera is
never rolled. Pixel ``(c, k)`` (column, row; row 0 at the top) looks along
``forward + sx[c] right + sy[k] true_up``, with ``sx``, ``sy`` the pixel centres' offsets
on the image plane at distance 1.

A vertical viewing direction (straight down, a nadir view, or straight up) has no
horizontal ``forward x up``. It takes the frame of a camera heading north (towards ``-y``,
row 0 of a north-up raster) that pitches down (or up) to the vertical: ``right = (-1, 0,
0)``, so a nadir image has north (``-y``) at its top, continuous with a camera heading
north as it tilts down. A custom ``up`` parallel to the viewing direction is refused.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["MAX_COORDINATE", "check_camera", "pinhole_frame", "primary_directions"]

#: largest |coordinate| of a camera position or look_at, in cells
MAX_COORDINATE = 1e12

#: a direction whose horizontal part is below this (relative) is taken as vertical
_VERTICAL = 1e-12


def check_camera(position, look_at, fov, width, height):
    """``(position, look_at, fov, width, height)`` of any camera, checked and converted:
    two float64 3-vectors of finite coordinates within ``MAX_COORDINATE``, ``fov`` a float
    in (0, 180) degrees, each image side an int in [1, 2^24]. ValueError or TypeError
    naming the argument and its value."""
    points = []
    for name, value in (("position", position), ("look_at", look_at)):
        try:
            point = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError):
            point = None
        if point is None or point.shape != (3,) or not np.all(np.abs(point) <= MAX_COORDINATE):
            shown = value if point is None or point.shape != (3,) else point.tolist()
            raise ValueError(f"{name}: expected a 3-vector of finite coordinates within "
                             f"+-{MAX_COORDINATE:g} cells, got {shown!r}")
        points.append(point)
    try:
        degrees = float(fov)
    except (TypeError, ValueError):
        degrees = math.nan
    if not 0 < degrees < 180:
        raise ValueError(f"fov: expected degrees in (0, 180), got {fov!r}")
    for name, value in (("width", width), ("height", height)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
            raise TypeError(f"{name}: expected an integer, got {value!r}")
        if not 1 <= int(value) <= 1 << 24:
            raise ValueError(f"{name}: expected a size in [1, 2^24], got {value}")
    return points[0], points[1], degrees, int(width), int(height)


def pinhole_frame(position, look_at, fov, width, height, *, up=None):
    """The camera frame and the per-pixel screen offsets of a pinhole camera.

    Parameters
    ----------
    position, look_at : array_like (3,)
        Camera and target, finite, within ``MAX_COORDINATE`` (grid coordinates: x =
        column, y = row, z = height, cell units).
    fov : float
        Horizontal field of view, degrees in (0, 180).
    width, height : int
        Image size in pixels, each in [1, 2^24].
    up : array_like (3,), optional
        The world's up (default ``+z``); the image is never rolled about it.

    Returns
    -------
    frame : ndarray (14,) float64
        position (3), forward (3), right (3), true_up (3), ``tan(fov/2)`` and the vertical
        half extent ``tan(fov/2) height / width``.
    sx : ndarray (width,) float64
        Horizontal offsets of the pixel centres, ``((c + 0.5) / width * 2 - 1) tan(fov/2)``.
    sy : ndarray (height,) float64
        Vertical offsets, ``(1 - (k + 0.5) / height * 2) * half_h`` (row 0 at the top).

    Raises
    ------
    ValueError
        A position, look_at or up not a finite 3-vector within ``MAX_COORDINATE``,
        ``look_at == position``, a custom ``up`` parallel to the viewing direction, ``fov``
        outside (0, 180) degrees, or an image side outside [1, 2^24].
    TypeError
        ``width`` or ``height`` not an integer.
    """
    position, look_at, fov, width, height = check_camera(position, look_at, fov, width, height)
    forward = look_at - position
    if not np.linalg.norm(forward) > 0:
        raise ValueError("look_at: must differ from position")
    forward = forward / np.linalg.norm(forward)
    if up is None:
        world_up = np.array([0.0, 0.0, 1.0])
    else:
        world_up = np.asarray(up, dtype=np.float64)
        if world_up.shape != (3,) or not np.all(np.isfinite(world_up)) \
                or not np.linalg.norm(world_up) > 0:
            raise ValueError(f"up: expected a finite non-zero 3-vector, got {world_up.tolist()}")
    right = np.cross(forward, world_up)
    if np.linalg.norm(right) > _VERTICAL * np.linalg.norm(world_up):
        right /= np.linalg.norm(right)
    elif up is None:
        # vertical: the frame of a camera heading north (-y), tilted to the vertical
        right = np.array([-1.0, 0.0, 0.0])
    else:
        raise ValueError(f"up: {world_up.tolist()} is parallel to the viewing direction "
                         f"{forward.tolist()}; any up not parallel to it works (or leave "
                         "up unset: vertical views then take the north-heading frame)")
    true_up = np.cross(right, forward)
    half_w = math.tan(math.radians(fov) / 2)
    half_h = half_w * height / width
    sx = ((np.arange(width) + 0.5) / width * 2 - 1) * half_w
    sy = (1 - (np.arange(height) + 0.5) / height * 2) * half_h
    frame = np.concatenate([position, forward, right, true_up, [half_w, half_h]])
    return frame, np.ascontiguousarray(sx), np.ascontiguousarray(sy)


def primary_directions(frame, sx, sy):
    """Unit directions of the primary rays of :func:`pinhole_frame`'s camera, one per pixel
    in row-major order (row 0 at the top): float64 ``(len(sy) * len(sx), 3)``."""
    forward, right, true_up = frame[3:6], frame[6:9], frame[9:12]
    d = (forward[None, None, :] + sx[None, :, None] * right[None, None, :]
         + sy[:, None, None] * true_up[None, None, :]).reshape(-1, 3)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d
