"""Hillshaded previews of height fields (PNG, via Pillow)."""
from __future__ import annotations

import numpy as np

__all__ = ["hillshade", "write_png"]


def hillshade(heights, azimuth=315.0, altitude=45.0, exaggeration=1.0) -> np.ndarray:
    """Lambertian shading in [0, 1] under a sun at ``azimuth`` (degrees clockwise from
    north = +y) and ``altitude`` (degrees above the horizon); heights in cell units."""
    h = np.asarray(heights, dtype=np.float64) * exaggeration
    dz_dy, dz_dx = np.gradient(h)
    az, alt = np.radians(azimuth), np.radians(altitude)
    sun = np.array([np.sin(az) * np.cos(alt), np.cos(az) * np.cos(alt), np.sin(alt)])
    normal = np.stack([-dz_dx, -dz_dy, np.ones_like(h)])
    normal /= np.linalg.norm(normal, axis=0)
    return np.clip(np.tensordot(sun, normal, axes=1), 0.0, 1.0)


def write_png(path, heights, **shade) -> None:
    """Write a grayscale preview: hillshade blended with normalised height, y up."""
    from PIL import Image

    h = np.asarray(heights, dtype=np.float64)
    span = h.max() - h.min()
    level = (h - h.min()) / span if span > 0 else np.zeros_like(h)
    image = 0.7 * hillshade(h, **shade) + 0.3 * level
    pixels = np.flipud(np.round(image * 255)).astype(np.uint8)  # row 0 (y = 0) at the bottom
    Image.fromarray(pixels, mode="L").save(path)
