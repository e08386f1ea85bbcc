"""Pictures: hillshaded previews of height fields (PNG, via Pillow) and readable pictures
of terrain products (PNG, via matplotlib: colour bar with units, title with parameters)."""
from __future__ import annotations

import textwrap

import numpy as np

__all__ = ["hillshade", "write_png", "product_png"]


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


def product_png(path, array, field=None, *, product, units, params=None, observers=None,
                cmap="viridis", robust=(2.0, 98.0), border=None, dpi=110) -> str:
    """Draw a terrain product as a PNG that can be read quantitatively (matplotlib).

    Parameters
    ----------
    path : str or path-like
    array : (rows, cols) array
        The product in the field's stored orientation (as the products return it); bool
        products are drawn as 0/1.
    field : HeightField, optional
        Gives the orientation (drawn north up), the map extent of a georeferenced field
        (axes in its CRS's unit) and the void mask.
    product, units : str
        The title's product name and the colour bar's label.
    params : dict, optional
        The product's parameters, listed in the title.
    observers : sequence of (col, row), optional
        Grid coordinates (stored orientation) marked with a red cross.
    cmap : str
    robust : (low, high) percentiles
        Colour limits from these percentiles of the valid pixels (so that a few extreme
        pixels do not squeeze the colours); None for the full range.
    border : float, optional
        A value meaning "nothing there" (the horizon's -90 degrees, or -pi/2 rad),
        masked like the voids. NaN and void pixels are always masked (drawn grey).

    Returns
    -------
    str
        The path written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    values = np.asarray(array, dtype=np.float64)
    if values.ndim != 2:
        raise ValueError(f"array: expected a 2D product, got shape {values.shape}")
    mask = ~np.isfinite(values)
    if field is not None and field.nodata_mask is not None:
        mask |= np.asarray(field.nodata_mask)
    if border is not None:
        mask |= np.isclose(values, border, rtol=0, atol=1e-12)
    rows, cols = values.shape
    flip = field is not None and not field.north_up
    up = field.to_north_up if field is not None else (lambda a: a)
    shown = np.ma.masked_array(up(values), up(mask))
    valid = shown.compressed()
    if np.asarray(array).dtype == bool:
        vmin, vmax = 0.0, 1.0
    elif valid.size and robust is not None:
        vmin, vmax = (float(v) for v in np.percentile(valid, robust))
    elif valid.size:
        vmin, vmax = float(valid.min()), float(valid.max())
    else:
        vmin, vmax = 0.0, 1.0
    if vmin == vmax:
        vmin, vmax = vmin - 0.5, vmax + 0.5
    georef = field is not None and field.transform is not None
    if georef:
        # the north-up picture's corners in map units (pixel edges)
        xs = [field.grid_to_map(c, 0)[0] for c in (-0.5, cols - 0.5)]
        ys = [field.grid_to_map(0, r)[1] for r in (-0.5, rows - 0.5)]
        extent = (min(xs), max(xs), min(ys), max(ys))
    else:
        extent = (-0.5, cols - 0.5, rows - 0.5, -0.5)
    colours = matplotlib.colormaps[cmap].with_extremes(bad="0.75")
    aspect = "equal" if georef or field is None or field.dx == field.dy else field.dy / field.dx
    fig, ax = plt.subplots(figsize=(7.5, 6.5), constrained_layout=True)
    image = ax.imshow(shown, cmap=colours, vmin=vmin, vmax=vmax, extent=extent,
                      interpolation="nearest", aspect=aspect)
    bar = fig.colorbar(image, ax=ax, shrink=0.85)
    bar.set_label(units)
    if observers is not None:
        for col, row in np.atleast_2d(np.asarray(observers, dtype=np.float64)):
            if georef:
                x, y = field.grid_to_map(col, row)
            else:
                x, y = col, field.north_up_row(row) if field is not None else row
            ax.plot([x], [y], marker="x", color="red", markersize=10, mew=2)
    lengths = ("max_distance", "observer_height", "target_height")
    unit = f" {field.unit}" if field is not None and field.unit != "cell" else ""
    text = ", ".join(f"{k}={_short(v)}{unit if k in lengths and v is not None else ''}"
                     for k, v in (params or {}).items())
    # wrapped: on one line a product's parameters ran past both edges of the figure
    text = textwrap.fill(text, width=80, break_long_words=False, break_on_hyphens=False)
    name = field.name if field is not None else ""
    ax.set_title(f"{product}{' of ' + name if name else ''}" + (f"\n{text}" if text else ""),
                 fontsize=10)
    if georef:
        unit = field.unit
        ax.set_xlabel(f"x ({unit})")
        ax.set_ylabel(f"y ({unit})")
    else:
        ax.set_xlabel("column")
        ax.set_ylabel("row (north up)" if field is not None and flip else "row")
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return str(path)


def _short(value):
    if isinstance(value, float):
        return f"{value:.4g}"
    if isinstance(value, (list, tuple, np.ndarray)) and len(value) > 6:
        return f"{len(value)} values"
    return str(value)
