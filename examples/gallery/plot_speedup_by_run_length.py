"""
Speedup by run length
=====================

Henning & Stephenson (2004) walk a ray across a grid run by run instead of cell by cell,
and measure the gain by the ray's *mean run length* ``r``: the mean number of cells of a
run, a stretch of consecutive cells with one minor index. A ray at azimuth ``atan(1/r)``
from its major axis has mean run length ``r``. This example runs a small version of that sweep:
first hits on the two-triangle surface of a 256 x 256 fBm field, 1000 rays per run length,
for the cell DDA (Amanatides & Woo 1987), the exact run walk and the two max-mipmap walks
(Tevs, Ihrke & Seidel 2008).

**What is measured, and what it is worth.** The left panel is *time measured while these
pages were built*: the C loop's own clock (``Hits.elapsed_ns``), the median of 5 repeats
run side by side, as a ratio over ``dda``. It is not the reference figure: the machine
that built the docs may be loaded, the field is small enough to stay in cache, and caches
are not flushed between runs (the study does flush them; see the method page). The
reference figures are ``reports/reproduce/speedup.md``, made by ``hftrace reproduce``.
The right panel is not a timing: it is the exact work each walk did, counted by the
kernels themselves (cells visited by the cell walk, runs visited by the run walk, per
ray). Those counts are the same on every machine.
"""
import matplotlib.pyplot as plt
import numpy as np

import algos
import datasets_gen
from datasets_gen import rays

# %%
# A small seeded field and, for each run length, 1000 first-hit rays: directions of slope
# ``1/r`` in all eight octants, 5 to 20 degrees below the horizon, starting one cell
# above the highest point (the rays of the study, ``docs/METHOD.md``, "Rays").
field = algos.HeightField(datasets_gen.load("fbm", size=256, seed=1).heights)
top = float(field.heights.max()) + 1.0
run_lengths = [1, 2, 5, 10, 25, 50]
kernels = ["dda", "runs", "dda_maxmip", "runs_maxmip"]
repeats = 5

ratios = {name: [] for name in kernels}
cells_per_ray, runs_per_ray = [], []
for r in run_lengths:
    batch = rays.by_run_length(r, 1000, field.heights.shape[::-1], seed=7, order="octant",
                               elevation=(5.0, 20.0), height=top)
    times = {name: [] for name in kernels}
    for _ in range(repeats):  # the kernels interleaved, as the study does
        for name in kernels:
            hits = algos.intersect(name, field, batch.origins, batch.directions,
                                   outputs=("t",), threads=1)
            times[name].append(hits.elapsed_ns)
    for name in kernels:
        ratios[name].append(np.median(times["dda"]) / np.median(times[name]))
    # the exact work of the walk up to its hit, from the kernels' own statistics
    counts = algos.intersect("runs", field, batch.origins, batch.directions,
                             outputs=("stats",), threads=1).stats
    cells_per_ray.append(counts["cells_visited"].mean())
    runs_per_ray.append(counts["runs_visited"].mean())

# %%
# The two panels: measured time ratios (this build's machine) and exact counts.
fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4))
for name in kernels:
    left.plot(run_lengths, ratios[name], marker="o", label=name)
left.axhline(1.0, color="grey", linewidth=0.8)
left.set_xscale("log")
left.set_xlabel("mean run length r")
left.set_ylabel("median time of dda / median time of kernel")
left.set_title("Measured while building the docs\n(fBm 256², 1000 rays, warm caches)")
left.legend()
right.plot(run_lengths, cells_per_ray, marker="o", label="cells visited per ray")
right.plot(run_lengths, runs_per_ray, marker="s", label="runs visited per ray")
right.set_xscale("log")
right.set_yscale("log")
right.set_xlabel("mean run length r")
right.set_ylabel("count per ray (exact, machine-independent)")
right.set_title("Work of the exact walks up to the hit")
right.legend()
fig.tight_layout()
plt.show()

# %%
# A run walk saves work in proportion to ``r`` (one step per run instead of one per cell),
# but a first hit still tests the cells it crosses, which is why the measured ratio stays
# far below the count ratio; the method and the reports explain where the time goes.
