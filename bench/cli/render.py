"""``hftrace render``: a pinhole image (``algos.render``) written as files.

Outputs (``OUT`` is the path prefix, default ``results/render/render``):

* ``OUT.exr``: float32 channels ``Z`` (distance along the unit view ray, ``inf`` on a
  miss), ``N.x``, ``N.y``, ``N.z`` (unit normal, NaN on a miss), ``cellsVisited`` and
  ``runsVisited`` (the intersector's per-ray statistics);
* ``OUT.png``: the shaded preview (``algos.render.shade``);
* with ``diff=(A, B)``: ``OUT-diff.exr`` (``dZ`` = Z_A - Z_B, ``visitRatio`` =
  cellsVisited_A / cellsVisited_B) and ``OUT-diff.png``, the depth difference and a
  log2 heatmap of the visit ratio side by side, so where runs win shows at a glance; the
  printed summary gives the fraction of pixels whose hit cell differs
  (``algos.raster.diff_images``).

``--algorithm`` (and either side of ``--diff``) is any intersector or any rasteriser
(``zbuffer``, ``painter``, ``watkins``, ``warnock``, ``floating_horizon``); a rasteriser
writes zeros in ``cellsVisited`` and ``runsVisited``.
A file is read by ``datasets_gen.load_file`` and that HeightField is rendered as it is,
so the image is ``algos.render(datasets_gen.load_file(FILE), ...)`` exactly: heights in
the pixel size's unit (a DEM's metres) are divided by the square pixel size, the camera
(``--camera``, ``--look-at``) and ``--fog`` are in cell units. A file with rectangular
pixels is refused (resample it, e.g. ``gdalwarp -tr D D``), and so is one with voids
unless ``--fill min|VALUE`` fills them, both before any camera is computed.
"""
from __future__ import annotations

import os

import numpy as np

import algos
from algos.render import PROJECTIONS

from .args import add_plugin, load_plugins, param, positive_int, results_dir, vector
from .files import save_png, write_exr
from .terrain_field import fill_policy, note_undeclared_nodata

__all__ = ["render_files", "load_render_field", "register"]


def load_render_field(dataset, size=None, seed=1, params=None, fill=None, nodata=None):
    """The HeightField ``hftrace render`` draws: a file through ``datasets_gen.load_file``
    (heights in the pixel size's unit; a ``.npy`` is memory-mapped), else a generated or
    embedded dataset (cell units).

    ``fill`` is ``--fill``: None keeps a file's voids (then refused here), ``"min"`` or a
    height (a number or its text) fills them; ``nodata`` is ``--nodata``, the void value
    of a file that declares none. A file that holds a common nodata value (such as
    -9999) as its lowest height without declaring it gets a note on stderr: taken as a
    height, it moves the default camera far above the surface. Raises ValueError naming the file and what
    to do, before any camera is computed: voids (``--fill``), rectangular pixels
    (resample to square ones, e.g. ``gdalwarp -tr D D``), ``fill`` for a dataset."""
    import datasets_gen


    path = str(dataset)
    if not os.path.exists(path):
        for option, value, verb in (("fill", fill, "fills"), ("nodata", nodata, "declares")):
            if value is not None:
                raise ValueError(f"--{option}: {verb} the voids of a file; {path} is a "
                                 "generated or embedded dataset")
        return datasets_gen.load(dataset, size=size, seed=seed, **(params or {}))
    policy, fill_value = fill_policy(None if fill is None else str(fill))
    field = datasets_gen.load_file(path, nodata_policy=policy, fill_value=fill_value,
                                   nodata=nodata)
    note_undeclared_nodata(field, path)
    if field.dx != field.dy:
        d = min(field.dx, field.dy)
        raise ValueError(f"{path}: rectangular pixels ({field.dx:g} x {field.dy:g} "
                         f"{field.unit}); a render traces in cell units and needs square "
                         f"pixels: resample first, e.g. gdalwarp -tr {d:g} {d:g} -r bilinear "
                         f"{path} square.tif")
    if field.nodata_mask is not None:
        row, col = (int(v) for v in np.argwhere(field.nodata_mask)[0])
        count = int(np.count_nonzero(field.nodata_mask))
        raise ValueError(f"{path}: {count} void (nodata) sample{'s' * (count != 1)}, the "
                         f"first at (row {row}, col {col}); a render needs every height: "
                         "give --fill min (the lowest height) or --fill VALUE")
    return field


def render_files(dataset="fbm", size=None, seed=1, algorithm="runs", surface="triangles",
                 width=640, height=360, position=None, look_at=None, fov=60.0, fog=0.0,
                 out="render", diff=None, params=None, echo=print, threads=None, fill=None,
                 projection="pinhole", nodata=None):
    """Render with ``algos.render``, write the files (module docstring), return their paths
    (keys exr, png, and with ``diff`` diff_exr, diff_png).

    ``dataset`` is a dataset name or a file (:func:`load_render_field`; ``.npy`` files are
    memory-mapped, so a field larger than memory renders). The loaded HeightField itself
    is rendered, so a file's image is exactly
    ``algos.render(datasets_gen.load_file(FILE), ...)``: heights in the pixel size's unit
    are divided by the (square) pixel size, and ``position``, ``look_at`` and ``fog``
    are in cell units. ``fill`` and ``nodata`` as in :func:`load_render_field`; ``threads`` as in
    ``algos.intersect`` (default: every core), the image is bit-identical for every
    value. ``projection`` is ``algos.render``'s (pinhole, level or orthographic)."""
    field = load_render_field(dataset, size=size, seed=seed, params=params, fill=fill,
                              nodata=nodata)
    if os.path.exists(str(dataset)):
        dataset = os.path.basename(str(dataset))
    heights = field.heights
    os.makedirs(os.path.dirname(out) or ".", exist_ok=True)
    view = dict(surface=surface, width=width, height=height, position=position,
                look_at=look_at, fov=fov, threads=threads, projection=projection)
    image = algos.render(field, algorithm, fog=fog, **view)
    write_exr(f"{out}.exr", {"Z": image.depth, "N.x": image.normal[..., 0],
                             "N.y": image.normal[..., 1], "N.z": image.normal[..., 2],
                             "cellsVisited": image.cells_visited.astype(np.float32),
                             "runsVisited": image.runs_visited.astype(np.float32)})
    save_png(f"{out}.png", image.rgb)
    paths = dict(exr=f"{out}.exr", png=f"{out}.png")
    echo(f"{algorithm} on {dataset} {heights.shape}: {width}x{height} rays in "
         f"{image.elapsed_ns / 1e6:.1f} ms, {np.isfinite(image.depth).mean():.1%} hit; "
         f"wrote {out}.exr, {out}.png")
    if diff:
        a, b = diff
        first, second = algos.render(field, a, **view), algos.render(field, b, **view)
        za, zb = first.depth, second.depth
        with np.errstate(invalid="ignore", divide="ignore"):
            dz = np.where(np.isfinite(za) & np.isfinite(zb), za - zb,
                          np.where(np.isfinite(za) == np.isfinite(zb), 0.0, np.nan))
            ratio = _steps(first) / np.maximum(_steps(second), 1)
        write_exr(f"{out}-diff.exr", {"dZ": dz, "visitRatio": ratio})
        _diff_png(f"{out}-diff.png", dz, ratio, a, b)
        paths.update(diff_exr=f"{out}-diff.exr", diff_png=f"{out}-diff.png")
        stats = algos.raster.diff_images(first, second)
        echo(f"diff {a} - {b}: hit cell differs on {stats['cell_differs']:.4%} of "
             f"{stats['pixels']} pixels, {stats['hit_by_one']} hit by one only; |dZ| max "
             f"{stats['depth_max_abs']:.3g}, median {stats['depth_median_abs']:.3g}; median "
             f"visit ratio {np.median(ratio):.2f}; wrote {out}-diff.exr, {out}-diff.png")
        paths["diff"] = stats
    return paths


def _steps(image):
    """Traversal steps per pixel: runs for a run kernel, cells for a cell kernel."""
    runs = image.runs_visited
    return np.where(runs > 0, runs, image.cells_visited).astype(np.float64)


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


def _check_renderer(name, option="--algorithm"):
    """An intersector or a rasteriser name, else ValueError naming ``option`` and listing
    both."""
    if name in algos.raster.RASTERISERS:
        return
    try:
        algos.get_intersector(name)
    except ValueError:
        raise ValueError(f"{option}: unknown renderer {name!r}; valid: "
                         f"{', '.join(algos.INTERSECTORS + tuple(algos.raster.RASTERISERS))}") from None


def render_command(args):
    """``hftrace render``: register ``--plugin`` kernels, check the renderer names, then
    :func:`render_files`."""
    load_plugins(args)
    _check_renderer(args.algorithm)
    for name in args.diff or ():
        _check_renderer(name, "--diff")
    render_files(dataset=args.dataset, size=args.size, seed=args.seed, algorithm=args.algorithm,
                 surface=args.surface, width=args.width, height=args.height,
                 position=args.camera, look_at=args.look_at, fov=args.fov, fog=args.fog,
                 out=args.out, diff=args.diff, params=dict(args.param or []),
                 threads=args.threads, fill=args.fill, projection=args.projection,
                 nodata=args.nodata)
    return 0


def register(sub):
    """Add ``render`` to the sub-parsers ``sub``."""
    p = sub.add_parser("render", help="a pinhole image (OpenEXR + PNG) with any intersector")
    p.add_argument("dataset", help="a generator or embedded field (hftrace datasets list), or "
                                   "a file (any raster GDAL reads, .npy memory-mapped, PNG, "
                                   "EXR): heights in its pixel size's unit, square pixels")
    p.add_argument("--fill", default=None, metavar="min|VALUE",
                   help="fill a file's voids (nodata) with its lowest height or VALUE; "
                        "without it a file with voids is refused")
    p.add_argument("--nodata", type=float, default=None, metavar="VALUE",
                   help="the nodata value of a file that declares none (e.g. -9999): its "
                        "samples are voids (then give --fill)")
    p.add_argument("--size", type=positive_int, default=None)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--param", type=param, action="append", metavar="NAME=VALUE")
    p.add_argument("--algorithm", default="runs",
                   help="an intersector (hftrace list) or a rasteriser: "
                        f"{', '.join(algos.raster.RASTERISERS)}")
    p.add_argument("--surface", default="triangles", choices=algos.SURFACES)
    p.add_argument("--width", type=positive_int, default=640)
    p.add_argument("--height", type=positive_int, default=360)
    p.add_argument("--camera", type=vector, default=None, help="x,y,z (default: above a corner)")
    p.add_argument("--look-at", type=vector, default=None, help="x,y,z (default: the centre)")
    p.add_argument("--projection", default="pinhole", choices=PROJECTIONS,
                   help="pinhole; level (no pitch, a vertical lens shift centres --look-at: "
                        "each image column one vertical plane); orthographic")
    p.add_argument("--fov", type=float, default=60.0, help="horizontal field of view, degrees")
    p.add_argument("--fog", type=float, default=0.0,
                   help="height-fog density sigma0 per cell at the lowest point (0: none)")
    p.add_argument("--diff", nargs=2, metavar=("A", "B"), default=None,
                   help="also compare two renderers (intersectors or rasterisers): the depth "
                        "difference, the step ratio and the fraction of differing hit cells")
    add_plugin(p)
    default = os.path.join(results_dir("render"), "render")
    p.add_argument("--out", default=default, help=f"output path prefix (default {default})")
    p.add_argument("--threads", type=positive_int, default=None,
                   help="default: every core in the affinity (the image is the same)")
    p.set_defaults(func=render_command)
