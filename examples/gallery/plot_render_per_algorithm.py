"""
A render per algorithm
======================

Every first-hit intersector in the registry (``algos.INTERSECTORS``) and every rasteriser
(``algos.RASTERISERS``) draws the same small view of the same field with the same pinhole
camera. The exact and float64 intersectors find the same cell on every pixel here; the
approximate ones (ray marchers, relaxed cone stepping, the floating horizon) and the float32
Embree peers differ where their documented error shows (Embree's triangles leave out the
field's side walls, which the tracers report as hits). Below each picture: the kernel's accuracy class and the pixels
whose hit cell differs from ``dda``'s.
"""
import matplotlib.pyplot as plt
import numpy as np

import algos
import datasets_gen

# %%
# A 128 x 128 seeded fBm field, heights in cell units, and a 96 x 54 pixel image.
heights = datasets_gen.load("fbm", size=128, seed=3).heights
width, height = 96, 54
reference = algos.render(heights, "dda", width=width, height=height, threads=1)

names = list(algos.INTERSECTORS) + list(algos.RASTERISERS)
columns = 4
rows = -(-len(names) // columns)
fig, axes = plt.subplots(rows, columns, figsize=(2.6 * columns, 1.9 * rows))
for ax, name in zip(axes.flat, names):
    image = algos.render(heights, name, width=width, height=height, threads=1)
    if name in algos.RASTERISERS:
        kind = "rasteriser"
    else:
        kind = algos.get_intersector(name).accuracy
    differ = np.mean(np.any(image.cell != reference.cell, axis=-1))
    ax.imshow(image.rgb)
    ax.set_title(name, fontsize=9)
    ax.set_xlabel(f"{kind}; {100 * differ:.1f} % cells differ", fontsize=7)
    ax.set_xticks([])
    ax.set_yticks([])
for ax in axes.flat[len(names):]:
    ax.axis("off")
fig.tight_layout()
plt.show()
