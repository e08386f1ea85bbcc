"""
Terrain products of the embedded DEM
====================================

The embedded DEM is the Jacksboro fault from matplotlib's sample data, converted to
metres and resampled onto square cells of about 74 m (``datasets_gen.load("jacksboro")``).
On it, the four products of :mod:`algos` that walk parallel rays from every vertex:

- the horizon angle toward one azimuth (exact on the two-triangle surface),
- the shadows of a sun at azimuth 135 degrees, 20 degrees high,
- the sky-view factor over 16 rational azimuths (Zakšek, Oštir & Kokalj 2011),
- the viewshed of an observer 10 m above the ground.

Azimuths are degrees clockwise from north; row 0 is north.
"""
import matplotlib.pyplot as plt
import numpy as np

import algos
import datasets_gen

field = datasets_gen.load("jacksboro")
rows, cols = field.heights.shape
print(f"{rows} x {cols} vertices, spacing {field.spacing} {field.unit}")

# %%
# The products, each on every vertex.
horizon_east = algos.horizon(field, [90.0], units="degrees")[0]
shadow = algos.shadows(field, azimuth=135.0, elevation=20.0)
svf = algos.sky_view_factor(field, 16, rational=True)
observer = (cols // 2, rows // 2)  # (x, y) grid coordinates: column, row
seen = algos.viewshed(field, observer, observer_height=10.0)

# %%
# One panel per product.
fig, axes = plt.subplots(2, 2, figsize=(10, 10))
# colour limits from the 1st to the 99th percentile: the vertices of the east edge, which
# have no surface toward the east, hold -90 degrees
low, high = np.nanpercentile(horizon_east, [1, 99])
panels = [
    (horizon_east, "Horizon angle toward the east (degrees)", "magma", (low, high)),
    (shadow, "Black: in shadow of a sun at azimuth 135°, 20° high", "Greys", None),
    (svf, "Sky-view factor, 16 azimuths", "viridis", None),
    (seen, "Yellow: visible from the star, 10 m up", "cividis", None),
]
for ax, (values, title, cmap, limits) in zip(axes.flat, panels):
    shown = ax.imshow(values.astype(float), cmap=cmap, **(dict(vmin=limits[0], vmax=limits[1]) if limits else {}))
    ax.set_title(title, fontsize=10)
    ax.set_xticks([])
    ax.set_yticks([])
    if values.dtype != bool:
        fig.colorbar(shown, ax=ax, shrink=0.75)
axes.flat[3].plot(*observer, marker="*", color="red", markersize=12)
fig.tight_layout()
plt.show()

# %%
# What fraction of the DEM each product marks.
print(f"in shadow: {np.mean(shadow):.1%} of the vertices")
print(f"visible from the observer: {np.mean(seen):.1%}")
print(f"sky-view factor: {np.nanmin(svf):.3f} to {np.nanmax(svf):.3f}")
