"""``hftrace horizon|shadows|svf|viewshed``: the terrain products of ``algos.terrain`` on a
dataset or a file, written as GeoTIFF, EXR and PNG (north up). ``--dask`` computes them
tile by tile on a cluster (``bench/cli/terrain_dask.py``).
"""
from __future__ import annotations

import os

import numpy as np

import algos

from .args import param, positive_int, results_dir

__all__ = ["register", "terrain_product", "write_product", "load_terrain"]

#: The products: command -> help text
PRODUCTS = (("horizon", "horizon angles (degrees) along azimuths"),
            ("shadows", "cast shadows for a sun azimuth and elevation"),
            ("svf", "sky-view factor (Zaksek et al. 2011)"),
            ("viewshed", "what one or more observers see"))


def load_terrain(args):
    """A HeightField from a dataset name or a file (GeoTIFF, PNG, EXR, .npy)."""
    import datasets_gen

    source = args.source
    if os.path.exists(source):
        return datasets_gen.load_file(source)
    params = dict(args.param or [])
    return datasets_gen.load(source, size=args.size, seed=args.seed, **params)


def _observers(args):
    return [tuple(float(v) for v in o.split(",")) for o in args.observer]


def _azimuths(args):
    return None if not args.azimuths else [float(v) for v in args.azimuths.split(",")]


def terrain_product_dask(args):
    """The product tile by tile on a Dask cluster (``terrain_dask.run_product``)."""
    from . import terrain_dask

    hf = terrain_dask.open_source(args.source, args.chunk, size=args.size, seed=args.seed,
                                  params=dict(args.param or []))
    kind = args.command
    options = dict(max_distance=args.max_distance, algorithm=args.algorithm,
                   worker_memory=args.worker_memory)
    if kind == "horizon":
        options["azimuths"] = _azimuths(args) or [0.0]
    elif kind == "svf":
        options.update(n_azimuths=args.n_azimuths, rational=args.rational)
    elif kind == "shadows":
        options.update(azimuth=args.azimuth, elevation=args.elevation)
    else:
        options.update(observers=_observers(args), observer_height=args.observer_height,
                       target_height=args.target_height, curvature=args.curvature,
                       refraction=args.refraction)
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    terrain_dask.run_product(kind, hf, args.out, args.dask, **options)
    return 0


def _bar(args, total, desc, unit):
    """A tqdm bar and the ``progress(done, total)`` callback that advances it."""
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit=unit, disable=args.no_progress or total == 1)

    def progress(done, _total):
        bar.update(done - bar.n)
    return bar, progress


def terrain_product(args):
    """Compute one product with ``algos`` and write it (:func:`write_product`)."""
    if args.dask:
        return terrain_product_dask(args)

    hf = load_terrain(args)
    kind = args.command
    common = dict(algorithm=args.algorithm, threads=args.threads)
    spacing = hf.spacing if hf.unit != "cell" else None
    md = args.max_distance
    if kind in ("horizon", "svf"):
        az = _azimuths(args)
        n = len(az) if az else (args.n_azimuths if kind == "svf" else 1)
        bar, progress = _bar(args, n, f"{kind} {hf.name}", "azimuth")
        with bar:
            if kind == "svf":
                result = algos.sky_view_factor(hf, args.n_azimuths, md, rational=args.rational,
                                               azimuths=az, progress=progress, **common)
            else:
                az = az or [0.0]
                angles = algos.horizon(hf, az, md, progress=progress, **common)
        if kind == "svf":
            outputs = {"svf": (result, "cividis", 0.0, 1.0)}
        else:
            outputs = {f"horizon_az{a:g}": (np.degrees(angles[k]), "magma", None, None)
                       for k, a in enumerate(az)}
    elif kind == "shadows":
        result = algos.shadows(hf, args.azimuth, args.elevation, max_distance=md, **common)
        outputs = {"shadows": (result.astype(np.float32), "gray_r", 0.0, 1.0)}
    else:
        observers = _observers(args) or [((hf.shape[1] - 1) / 2, (hf.shape[0] - 1) / 2)]
        bar, progress = _bar(args, len(observers), f"viewshed {hf.name}", "observer")
        with bar:
            seen = algos.viewshed(hf, observers, args.observer_height, args.target_height, md,
                                  curvature=args.curvature, refraction=args.refraction,
                                  progress=progress, **common)
        outputs = {"viewshed": (seen.astype(np.float32), "Greens", 0.0,
                                float(max(len(observers), 1)))}
    flip = (hf.params or {}).get("north") == "+y"
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    for name, (array, cmap, lo, hi) in outputs.items():
        shown = array[::-1] if flip else array  # files are written north-up
        prefix = args.out if len(outputs) == 1 else f"{args.out}_{name}"
        paths = write_product(prefix, shown, spacing=spacing, cmap=cmap, vmin=lo, vmax=hi)
        finite = array[np.isfinite(array)]
        print(f"{name}: {hf.name} {hf.shape[0]}x{hf.shape[1]}, min {finite.min():.4g}, "
              f"mean {finite.mean():.4g}, max {finite.max():.4g} -> {', '.join(paths)}")
    return 0


def write_product(prefix, array, *, spacing=None, cmap="viridis", vmin=None, vmax=None,
                  title=""):
    """prefix.tif (GeoTIFF-style float32 with the pixel scale), prefix.exr and prefix.png
    (a colour map). Returns the three paths."""
    import tifffile
    from matplotlib import colormaps
    from PIL import Image

    from .render import write_exr

    data = np.asarray(array, dtype=np.float32)
    extratags = []
    if spacing:
        extratags.append((33550, "d", 3, (float(spacing), float(spacing), 0.0), False))
    tifffile.imwrite(prefix + ".tif", data, extratags=extratags)
    write_exr(prefix + ".exr", {"Y": data})
    lo = float(np.nanmin(data)) if vmin is None else vmin
    hi = float(np.nanmax(data)) if vmax is None else vmax
    norm = (data - lo) / (hi - lo) if hi > lo else np.zeros_like(data)
    rgba = colormaps[cmap](np.clip(norm, 0, 1))
    Image.fromarray(np.round(rgba[..., :3] * 255).astype(np.uint8)).save(prefix + ".png")
    return [prefix + ".tif", prefix + ".exr", prefix + ".png"]


def register(sub):
    """Add horizon, shadows, svf and viewshed to the sub-parsers ``sub``."""
    for kind, text in PRODUCTS:
        p = sub.add_parser(kind, help=f"{text}: GeoTIFF, EXR and PNG")
        p.add_argument("source", nargs="?", default="jacksboro",
                       help="a dataset name (hftrace datasets list) or a file (default jacksboro)")
        p.add_argument("--size", type=positive_int, default=None)
        p.add_argument("--seed", type=int, default=1)
        p.add_argument("--param", type=param, action="append", metavar="NAME=VALUE")
        p.add_argument("--algorithm", default=None, help="default: chosen by measurement")
        p.add_argument("--threads", type=positive_int, default=None,
                       help="default: every core in the affinity")
        p.add_argument("--max-distance", type=float, default=None,
                       help="in the field's unit (metres for jacksboro)")
        default = os.path.join(results_dir(kind), kind)
        p.add_argument("--out", default=default, help=f"output path prefix (default {default})")
        p.add_argument("--no-progress", action="store_true")
        p.add_argument("--dask", default=None, metavar="ADDRESS",
                       help="tile by tile on a Dask cluster (a scheduler address, or local:N "
                            "for N single-threaded local workers); needs --max-distance; "
                            "files are read window by window, so they may exceed memory")
        p.add_argument("--chunk", type=positive_int, default=2048,
                       help="--dask: tile side in samples (default 2048)")
        p.add_argument("--worker-memory", default=None, metavar="BYTES",
                       help="--dask local:N: memory limit per worker, e.g. 600MiB")
        if kind == "horizon":
            p.add_argument("--azimuths", default=None, help="comma-separated degrees (default 0)")
        if kind == "svf":
            p.add_argument("--n-azimuths", type=positive_int, default=16)
            p.add_argument("--azimuths", default=None, help="comma-separated degrees")
            p.add_argument("--rational", action="store_true",
                           help="nearest rational azimuths: the exact sweep applies")
        if kind == "shadows":
            p.add_argument("--azimuth", type=float, default=315.0)
            p.add_argument("--elevation", type=float, default=30.0)
        if kind == "viewshed":
            p.add_argument("--observer", action="append", default=[], metavar="X,Y",
                           help="grid coordinates (repeatable; default the centre)")
            p.add_argument("--observer-height", type=float, default=1.75)
            p.add_argument("--target-height", type=float, default=0.0)
            p.add_argument("--curvature", action="store_true")
            p.add_argument("--refraction", type=float, default=0.13)
        p.set_defaults(func=terrain_product, command=kind)
