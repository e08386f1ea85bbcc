"""Cameras whose image columns are vertical planes: the level pinhole with a vertical
lens shift and the orthographic camera without roll (docs/plane.md).

Each returns the primary rays, one per pixel in row-major order (row 0 at the top), as
float64 ``(width * height, 3)`` origins and directions, in grid coordinates (x = column,
y = row, z = height, cell units). The rays of one image column share their horizontal
origin and direction bit for bit, so ``plane_maxmip`` traces each column as one plane.
``datasets_gen.rays.level_camera`` and ``orthographic`` wrap them as ray sets;
``algos.render(..., projection=...)`` renders with them.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["level_camera_rays", "orthographic_rays"]


def _film_axes(position, look_at):
    """The horizontal unit forward and right vectors of a camera at ``position`` facing
    ``look_at`` (without roll), and the target's horizontal distance and rise."""
    position = np.asarray(position, dtype=np.float64)
    look_at = np.asarray(look_at, dtype=np.float64)
    if position.shape != (3,) or look_at.shape != (3,) or not (
            np.all(np.isfinite(position)) and np.all(np.isfinite(look_at))):
        raise ValueError("position, look_at: expected finite 3-vectors")
    ahead = look_at[:2] - position[:2]
    distance = float(np.hypot(ahead[0], ahead[1]))
    if not distance > 0:
        raise ValueError("look_at: must differ from position horizontally (a level or "
                         "orthographic camera without roll cannot look straight down)")
    forward = ahead / distance
    right = np.array([forward[1], -forward[0]])
    return forward, right, distance, float(look_at[2] - position[2])


def _check_image(fov, width, height):
    if not 0 < fov < 180:
        raise ValueError(f"fov: expected degrees in (0, 180), got {fov}")
    if int(width) < 1 or int(height) < 1:
        raise ValueError(f"width, height: expected positive sizes, got {width} x {height}")


def level_camera_rays(position, look_at, fov, width, height):
    """Primary rays of a level pinhole camera with a vertical lens shift.

    The camera does not pitch: its film is vertical, and the principal point is shifted
    so that the image centre looks at ``look_at``. Every ray of an image column therefore
    has the same horizontal direction, bit for bit, and only ``dz`` changes down the
    column: each column is one vertical plane through the eye. Directions are *not*
    normalised (that would break the shared ``(dx, dy)``): ``d = forward + u right +
    (v + shift) up`` with ``forward`` and ``right`` horizontal unit vectors,
    ``up = (0, 0, 1)``, ``u`` in ``[-tan(fov/2), tan(fov/2)]`` and ``v`` scaled alike by
    ``height / width``; ``shift`` is the tangent of the angle from the eye up to
    ``look_at``. ``t`` is then in units of each ray's ``|d|``.

    Returns
    -------
    origins, directions : float64 (width * height, 3)
        Origins all ``position``.
    shift : float
        The vertical lens shift (a tangent).

    Raises
    ------
    ValueError
        A bad size, ``fov`` outside (0, 180) degrees, a non-finite point, or a
        ``look_at`` straight above or below the eye.
    """
    _check_image(fov, width, height)
    forward, right, distance, rise = _film_axes(position, look_at)
    width, height = int(width), int(height)
    shift = rise / distance
    half_w = math.tan(math.radians(fov) / 2)
    half_h = half_w * height / width
    u = ((np.arange(width) + 0.5) / width * 2 - 1) * half_w
    v = (1 - (np.arange(height) + 0.5) / height * 2) * half_h + shift
    # one (dx, dy) per column, the same float64 values in every row
    dx = np.broadcast_to(forward[0] + u * right[0], (height, width))
    dy = np.broadcast_to(forward[1] + u * right[1], (height, width))
    dz = np.broadcast_to(v[:, None], (height, width))
    d = np.stack([dx, dy, dz], axis=-1).reshape(-1, 3)
    o = np.tile(np.asarray(position, dtype=np.float64), (len(d), 1))
    return o, d, shift


def orthographic_rays(position, look_at, fov, width, height):
    """Primary rays of an orthographic camera without roll, all with the unit direction
    from ``position`` to ``look_at`` (any pitch).

    The film spans ``2 |look_at - position| tan(fov/2)`` cells across (the width a
    pinhole with that ``fov`` sees at the target), its height in proportion. Each ray's
    origin is slid along the view direction onto the vertical plane through
    ``position`` across the view, which changes no ray's line: the rays of an image column
    then share ``(ox, oy)`` and ``(dx, dy)`` bit for bit and differ only in ``oz``. ``t`` is
    measured from that vertical film, not from the tilted one.

    Returns
    -------
    origins, directions : float64 (width * height, 3)

    Raises
    ------
    ValueError
        A bad size or ``fov``, a non-finite point, or a view straight down or up.
    """
    _check_image(fov, width, height)
    forward2, right2, distance, rise = _film_axes(position, look_at)
    width, height = int(width), int(height)
    position = np.asarray(position, dtype=np.float64)
    slant = math.hypot(distance, rise)
    cos_p, sin_p = distance / slant, rise / slant
    half_w = slant * math.tan(math.radians(fov) / 2)
    half_h = half_w * height / width
    u = ((np.arange(width) + 0.5) / width * 2 - 1) * half_w
    v = (1 - (np.arange(height) + 0.5) / height * 2) * half_h
    # a film point position + u right + v up (up = (-sin_p forward2, cos_p)), slid by
    # v tan(p) along the view: horizontal position + u right, height v / cos(p)
    ox = np.broadcast_to(position[0] + u * right2[0], (height, width))
    oy = np.broadcast_to(position[1] + u * right2[1], (height, width))
    oz = np.broadcast_to((position[2] + v / cos_p)[:, None], (height, width))
    o = np.stack([ox, oy, oz], axis=-1).reshape(-1, 3)
    direction = np.array([cos_p * forward2[0], cos_p * forward2[1], sin_p])
    return o, np.tile(direction, (len(o), 1))
