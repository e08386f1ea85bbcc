"""``hftrace render``: a pinhole image of a height field with any intersector.

Outputs (``OUT`` is the path prefix):

* ``OUT.exr``: float32 channels ``Z`` (distance along the unit view ray, ``inf`` on a
  miss), ``N.x``, ``N.y``, ``N.z`` (unit normal, NaN on a miss), ``cellsVisited`` and
  ``runsVisited`` (the intersector's per-ray statistics);
* ``OUT.png``: a preview: terrain colour by height, a sun light (Lambert plus ambient)
  and, with ``fog > 0``, exponential height fog in closed form (the Hungarian lab's
  solution of dL/ds = -sigma L + q with sigma(z) = sigma0 e^(b z), q = (q0/sigma0) sigma):
  along a straight segment the optical depth is
  tau = sigma0 s (e^(b z1) - e^(b z0)) / (b (z1 - z0)), and
  L = L_surface e^(-tau) + L_fog (1 - e^(-tau));
* with ``diff=(A, B)``: ``OUT-diff.exr`` (``dZ`` = Z_A - Z_B, ``visitRatio`` =
  cellsVisited_A / cellsVisited_B) and ``OUT-diff.png``, the depth difference and a
  log2 heatmap of the visit ratio side by side, so where runs win shows at a glance.
"""
from __future__ import annotations

import math
import os

import numpy as np

import algos
import datasets_gen
from datasets_gen import rays as raysets

__all__ = ["default_camera", "render", "shade", "write_exr"]


def default_camera(heights):
    """Above the south-west corner, looking at the field's centre."""
    rows, cols = heights.shape
    span = float(heights.max() - heights.min())
    centre = np.array([(cols - 1) / 2, (rows - 1) / 2, float(np.mean(heights))])
    position = np.array([-0.15 * cols, -0.15 * rows, float(heights.max()) + 0.15 * max(rows, cols) + span])
    return position, centre


def trace(heights_or_field, algorithm, surface, width, height, position, look_at, fov,
          threads=None):
    rs = raysets.pinhole(position, look_at, fov, width, height)
    hits = algos.intersect(algorithm, heights_or_field, rs.origins, rs.directions, surface=surface,
                           outputs=("t", "cell", "normal", "stats"), threads=threads)
    shape = (height, width)
    z = hits.t.reshape(shape)  # unit directions: t is a distance
    normal = hits.normal.reshape(height, width, 3)
    stats = {k: v.reshape(shape) for k, v in hits.stats.items()}
    points = rs.origins + np.where(np.isfinite(hits.t), hits.t, 0)[:, None] * rs.directions
    return z, normal, stats, points.reshape(height, width, 3), hits


def write_exr(path, channels: dict) -> None:
    import OpenEXR

    data = {k: np.ascontiguousarray(v, dtype=np.float32) for k, v in channels.items()}
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with OpenEXR.File(header, data) as f:
        f.write(str(path))


def shade(z, normal, points, position, heights, fog=0.0, fog_falloff=None, sun=(315.0, 35.0)):
    """RGB in [0, 1]: terrain colour by height, Lambert sun plus ambient, height fog."""
    from matplotlib import colormaps

    hmin, hmax = float(heights.min()), float(heights.max())
    span = max(hmax - hmin, 1e-9)
    hit = np.isfinite(z)
    level = np.clip((points[..., 2] - hmin) / span, 0, 1)
    base = colormaps["terrain"](0.25 + 0.75 * level)[..., :3]
    az, alt = math.radians(sun[0]), math.radians(sun[1])
    light = np.array([math.sin(az) * math.cos(alt), math.cos(az) * math.cos(alt), math.sin(alt)])
    lambert = np.clip(np.nan_to_num(normal) @ light, 0, 1)
    colour = base * (0.25 + 0.75 * lambert[..., None])
    rows = z.shape[0]
    sky = np.linspace([0.55, 0.70, 0.90], [0.85, 0.90, 0.97], rows)[:, None, :]
    if fog > 0:
        b = fog_falloff if fog_falloff is not None else -3.0 / span
        z0 = position[2] - hmin
        z1 = points[..., 2] - hmin
        s = np.where(hit, z, 0.0)
        dz = z1 - z0
        with np.errstate(divide="ignore", invalid="ignore"):
            # optical depth of the segment; the limit sigma0 s e^(b z) where dz -> 0
            tau = np.where(np.abs(dz) > 1e-9,
                           fog * s * (np.exp(b * z1) - np.exp(b * z0)) / (b * dz),
                           fog * s * np.exp(b * z0))
        keep = np.exp(-np.clip(tau, 0, 50))[..., None]
        fog_colour = np.array([0.80, 0.84, 0.88])
        colour = colour * keep + fog_colour * (1 - keep)
    out = np.where(hit[..., None], colour, np.broadcast_to(sky, colour.shape))
    return np.clip(out, 0, 1)


def _save_png(path, rgb):
    from PIL import Image

    Image.fromarray(np.round(rgb * 255).astype(np.uint8), mode="RGB").save(path)


def render(dataset="fbm", size=None, seed=1, algorithm="runs", surface="triangles", width=640,
           height=360, position=None, look_at=None, fov=60.0, fog=0.0, out="render", diff=None,
           params=None, echo=print, threads=None):
    """Render, write the files, and return their paths.

    ``dataset`` is a dataset name or a file (``.npy`` files are memory-mapped, so a
    field larger than memory renders); ``threads`` as in ``algos.intersect``
    (default: every core), the image is bit-identical for every value."""
    if os.path.exists(str(dataset)):
        heights = datasets_gen.load_file(str(dataset)).heights
        dataset = os.path.basename(str(dataset))
    else:
        heights = datasets_gen.load(dataset, size=size, seed=seed, **(params or {})).heights
    field = algos.Field(heights)
    cam, centre = default_camera(heights)
    position = np.asarray(position if position is not None else cam, dtype=float)
    look_at = np.asarray(look_at if look_at is not None else centre, dtype=float)
    paths = {}
    z, normal, stats, points, hits = trace(field, algorithm, surface, width, height, position,
                                           look_at, fov, threads)
    write_exr(f"{out}.exr", {"Z": z, "N.x": normal[..., 0], "N.y": normal[..., 1],
                             "N.z": normal[..., 2],
                             "cellsVisited": stats["cells_visited"].astype(np.float32),
                             "runsVisited": stats["runs_visited"].astype(np.float32)})
    _save_png(f"{out}.png", shade(z, normal, points, position, heights, fog=fog))
    paths.update(exr=f"{out}.exr", png=f"{out}.png")
    echo(f"{algorithm} on {dataset} {heights.shape}: {width}x{height} rays in "
         f"{hits.elapsed_ns / 1e6:.1f} ms, {np.isfinite(z).mean():.1%} hit; wrote {out}.exr, {out}.png")
    if diff:
        a, b = diff
        za, _, sa, _, _ = trace(field, a, surface, width, height, position, look_at, fov, threads)
        zb, _, sb, _, _ = trace(field, b, surface, width, height, position, look_at, fov, threads)
        with np.errstate(invalid="ignore", divide="ignore"):
            dz = np.where(np.isfinite(za) & np.isfinite(zb), za - zb,
                          np.where(np.isfinite(za) == np.isfinite(zb), 0.0, np.nan))
            ratio = _steps(sa) / np.maximum(_steps(sb), 1)
        write_exr(f"{out}-diff.exr", {"dZ": dz, "visitRatio": ratio})
        _diff_png(f"{out}-diff.png", dz, ratio, a, b)
        paths.update(diff_exr=f"{out}-diff.exr", diff_png=f"{out}-diff.png")
        both = np.isfinite(dz)
        echo(f"diff {a} - {b}: max |dZ| {np.nanmax(np.abs(dz)) if both.any() else 0:.3g}, "
             f"{np.isnan(dz).sum()} pixels hit by one only; median visit ratio "
             f"{np.median(ratio):.2f}; wrote {out}-diff.exr, {out}-diff.png")
    return paths


def _steps(stats):
    """Traversal steps per pixel: runs for a run kernel, cells for a cell kernel."""
    runs = stats["runs_visited"]
    return np.where(runs > 0, runs, stats["cells_visited"]).astype(np.float64)


def _diff_png(path, dz, ratio, a, b):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6), dpi=110)
    lim = float(np.nanmax(np.abs(dz))) if np.isfinite(dz).any() else 1.0
    im = axes[0].imshow(dz, cmap="coolwarm", vmin=-lim or -1, vmax=lim or 1)
    axes[0].set_title(f"Z({a}) - Z({b})")
    fig.colorbar(im, ax=axes[0], shrink=0.8)
    with np.errstate(divide="ignore"):
        lr = np.log2(np.where(ratio > 0, ratio, np.nan))
    im = axes[1].imshow(lr, cmap="viridis")
    axes[1].set_title(f"log2 traversal steps: {a} / {b}")
    fig.colorbar(im, ax=axes[1], shrink=0.8)
    for ax in axes:
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
