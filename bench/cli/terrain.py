"""``hftrace horizon|shadows|svf|openness|viewshed``: the terrain products of ``algos.terrain`` on a
dataset or on any raster GDAL reads, written as a georeferenced GeoTIFF, a PNG with a colour
bar and an EXR (``--dask``: the GeoTIFF and the PNG; the EXR writer takes the whole product
in memory).

What a user's file gets (docs/CONVENTIONS.md, "Terrain products"):

* it is read through rasterio (``datasets_gen.load_file``): any compression, ``--band``,
  scale and offset applied, voids from its nodata mask;
* lengths (``--max-distance``, ``--observer-height``, ``--target-height``) are in the
  unit of its pixel size (the CRS's linear unit for a georeferenced DEM); a file without
  georeferencing takes ``--spacing D`` or ``DX,DY`` (default 1: cell units) and
  ``--unit m|km|ft|US survey foot`` (without it there is no real unit, and
  ``--curvature`` is refused);
* a geographic CRS (degrees) is refused with the ``gdalwarp`` command that fixes it, or
  reprojected with ``--reproject utm``; rotated geotransforms are refused;
* voids are nodata in every output and block no ray; ``--fill min|VALUE`` fills them
  instead (explicitly);
* outputs are written on the input's grid and orientation, with its CRS, geotransform and
  nodata, and the product's units and parameters as tags. Horizons and openness are in
  degrees unless ``--units radians``.
* ``--curvature`` (with ``--refraction``, default 1/7) lowers the surface for the earth's
  curvature on every product; it is off by default (docs/CONVENTIONS.md).
* ``viewshed --mode`` chooses GDAL's outputs (``-om``): ``normal`` visibility, ``ground``
  the smallest visible target height above the ground and ``dem`` its elevation (in the
  pixel size's unit: metres on a projected DEM), ``observer`` the smallest observer height
  that sees the vertex, ``angle`` the vertical view angle in degrees (the API returns
  radians). ``--visible-value/--invisible-value/--out-of-range-value`` (GDAL's ``-vv``,
  ``-iv``, ``-ov``, accepted under those names too) set the values of the normal mode
  (a uint8 file when all are integers in [0, 254], else float32) and the out-of-range
  value of the others (default nodata). The mode, unit and values are recorded as tags.

``--dask`` computes the products tile by tile on a cluster (``bench/cli/terrain_dask.py``).
The field is loaded by ``bench/cli/terrain_field.py`` and the options are checked by
``bench/cli/terrain_options.py``, which both commands share.
"""
from __future__ import annotations

import math
import os

import numpy as np

import algos

from .args import param, positive_int, results_dir
from .files import write_exr
from .terrain_field import load_terrain
from .terrain_options import (
    PRODUCTS,
    UNIT_CHOICES,
    azimuths_option,
    check_options,
    observers,
    observers_tag,
    output_prefix,
    product_options,
    spacing_arg,
    viewshed_values,
)

__all__ = ["register", "terrain_product"]

def _path_tags(stats):
    """What a product call records in its statistics (``return_stats=True``, an
    ``algos.terrain.TerrainStats``): the algorithm of each azimuth, and with
    ``--snap-denominator`` the azimuths used and the largest change in degrees."""
    tags = dict(paths=",".join(stats.paths))
    if stats.snapped_azimuths:
        tags.update(snapped_azimuths=[round(a, 12) for a in stats.snapped_azimuths],
                    snap_max_change_deg=stats.snap_max_change_deg)
    return tags


def _bar(args, total, desc, unit):
    """A tqdm bar and the ``progress(done, total)`` callback that advances it."""
    from tqdm import tqdm

    bar = tqdm(total=total, desc=desc, unit=unit, disable=args.no_progress or total == 1)

    def progress(done, _total):
        bar.update(done - bar.n)
    return bar, progress


def _viewshed(args, field, obs, common, progress):
    """The viewshed of the observers ``obs`` (a bool map for one, else a count), observers
    of one height in one ``algos.viewshed`` call; with ``--mode`` other than normal, or
    output values, the one observer's map."""
    values = viewshed_values(args)
    if args.mode != "normal" or values:
        if len(obs) != 1:
            raise ValueError(f"--observer: --mode {args.mode}"
                             f"{' and output values need' if values else ' needs'} one observer, "
                             f"got {len(obs)} (several give a count)")
        (col, row, height), = obs
        if args.mode == "observer" and height is not None:
            raise ValueError("--observer: --mode observer computes the observer height; give "
                             "the observer without one")
        return algos.viewshed(field, (col, row), args.observer_height if height is None
                              else height, args.target_height, args.max_distance,
                              curvature=args.curvature, refraction=args.refraction,
                              mode=args.mode, progress=progress, **values, **common)
    heights = [args.observer_height if h is None else h for _, _, h in obs]
    count = None
    done = 0
    for height in dict.fromkeys(heights):
        group = [(c, r) for (c, r, _), h in zip(obs, heights) if h == height]
        seen = algos.viewshed(field, group, height, args.target_height, args.max_distance,
                              curvature=args.curvature, refraction=args.refraction,
                              progress=lambda k, _n, base=done: progress(base + k, len(obs)),
                              **common)
        done += len(group)
        seen = seen.astype(np.uint16)
        count = seen if count is None else count + seen
    return count > 0 if len(obs) == 1 else count


def _on_the_line(obs, line):
    """The observers of a line (``field.params["line"]``, :func:`datasets_gen.load_file`
    with ``lines=True``) checked as :func:`algos.viewshed` checks a one-row array's: on
    the line, else ValueError with the API's message, in the line's coordinates."""
    rows, cols = line["shape"]
    r0, c0 = line["rows"][0], line["cols"][0]
    for k, (c, r, _) in enumerate(obs):
        x, y = c - c0, r - r0
        if not ((y == 0 and 0 <= x <= cols - 1) if rows == 1 else (x == 0 and 0 <= y <= rows - 1)):
            raise ValueError(f"observer[{k}]: ({x}, {y}) outside the footprint "
                             f"[0, {cols - 1}] x [0, {rows - 1}] of a one-"
                             f"{'row' if rows == 1 else 'column'} raster (a line)")


def terrain_product(args):
    """Compute one product with ``algos`` and write it (module docstring)."""
    if args.dask:
        from .terrain_dask import terrain_product_dask

        return terrain_product_dask(args)

    from datasets_gen.raster import save_product

    check_options(args)
    args.out = output_prefix(args)
    field = load_terrain(args)
    kind = args.command
    common = dict(algorithm=args.algorithm, threads=args.threads)
    if kind != "viewshed" and args.snap_denominator is not None:
        common["snap_denominator"] = args.snap_denominator
    # the horizon products' statistics: which path each azimuth took, and any snapping
    ran = {} if kind == "viewshed" else dict(return_stats=True)
    md = args.max_distance
    params = product_options(args, field)
    band_names, marks, border, cmap, window = None, None, None, "viridis", None
    curve = {} if kind == "viewshed" else dict(curvature=args.curvature,
                                                 refraction=args.refraction)
    if kind in ("horizon", "svf", "openness"):
        az = azimuths_option(args)
        n = len(az) if az else (1 if kind == "horizon" else args.n_azimuths)
        bar, progress = _bar(args, n, f"{kind} {field.name}", "azimuth")
        with bar:
            if kind == "svf":
                result = algos.sky_view_factor(field, args.n_azimuths, md, rational=args.rational,
                                               azimuths=az, progress=progress, **curve, **common,
                                               **ran)
                product, units, cmap = "sky_view_factor", "1", "cividis"
            elif kind == "openness":
                result = algos.openness(field, args.kind, args.n_azimuths, md, azimuths=az,
                                        rational=args.rational, units=args.units,
                                        progress=progress, **curve, **common, **ran)
                product, units, cmap = f"openness_{args.kind}", args.units, "cividis"
            else:
                az = az or [0.0]
                result = algos.horizon(field, az, md, units=args.units, progress=progress,
                                       **curve, **common, **ran)
                product, units, cmap = "horizon", args.units, "magma"
                border = -90.0 if args.units == "degrees" else -math.pi / 2
                band_names = [f"azimuth {a:g}" for a in az]
    elif kind == "shadows":
        result = algos.shadows(field, args.azimuth, args.elevation, max_distance=md, **curve,
                               **common, **ran)
        product, units, cmap = "shadows", "1 = in shadow", "gray_r"
    if kind != "viewshed":  # which path each azimuth took, and any snapping, as tags
        result, stats = result
        params.update(_path_tags(stats))
    else:
        obs = observers(args, field)
        line = field.params.get("line")
        if line is not None:  # held twice (two rows or columns): the line's own samples
            _on_the_line(obs, line)
            window = (slice(*line["rows"]), slice(*line["cols"]))
        params["observers"] = observers_tag(obs, field)  # as --observer-pixel counts
        bar, progress = _bar(args, len(obs), f"viewshed {field.name}", "observer")
        with bar:
            result = _viewshed(args, field, obs, common, progress)
        marks = [(c, r) for c, r, _ in obs]
        if window is not None:
            result = result[window]
            marks = [(c - window[1].start, r - window[0].start) for c, r in marks]
        product = "viewshed"
        units = "1 = visible" if len(obs) == 1 else "observers that see the vertex"
        cmap = "Greens"
        if args.mode == "angle":
            result = np.degrees(result)  # files hold degrees, as horizons
            units, cmap = "degrees", "magma"
        elif args.mode != "normal":
            units, cmap = field.unit, "viridis"
        elif viewshed_values(args):
            units = "output values (see the tags visible_value, invisible_value, " \
                    "out_of_range_value)"
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    paths = save_product(args.out, result, field, product=product, units=units, params=params,
                         band_names=band_names, observers=marks, cmap=cmap, border=border,
                         window=window)
    values = np.asarray(result, dtype=np.float32)
    channels = ({"Y": values} if values.ndim == 2
                else {name.replace(" ", "_"): v for name, v in zip(band_names, values)})
    write_exr(args.out + ".exr", channels)
    paths.append(args.out + ".exr")
    voids = None if field.nodata_mask is None else np.asarray(field.nodata_mask)
    if voids is not None and window is not None:
        voids = voids[window]
    valid = values[np.isfinite(values)] if voids is None else values[..., ~voids]
    valid = valid[np.isfinite(valid)]
    summary = (f"min {valid.min():.4g}, mean {valid.mean():.4g}, max {valid.max():.4g}"
               if valid.size else "no valid vertex")
    voids = 0 if voids is None else int(np.count_nonzero(voids))
    rows, cols = values.shape[-2:]
    print(f"{product} ({units}): {field.name} {rows}x{cols}"
          f"{f', {voids} void vertices (nodata)' if voids else ''}, {summary} -> "
          f"{', '.join(paths)}")
    return 0


def _curvature_options(p):
    """``--curvature`` and ``--refraction`` (as the viewshed's)."""
    p.add_argument("--curvature", action="store_true",
                   help="lower the surface for the earth's curvature and refraction (off by "
                        "default, as RVT; GRASS r.horizon applies it); needs metres")
    p.add_argument("--refraction", type=float, default=algos.DEFAULT_REFRACTION,
                   help=f"with --curvature: refraction coefficient (default 1/7 = "
                        f"{algos.DEFAULT_REFRACTION:.5f}, as GDAL and GRASS)")


def register(sub):
    """Add horizon, shadows, svf, openness and viewshed to the sub-parsers ``sub``."""
    for kind, text in PRODUCTS:
        p = sub.add_parser(kind, help=f"{text}: GeoTIFF, PNG and EXR")
        p.add_argument("source", nargs="?", default="jacksboro",
                       help="a raster file (any format GDAL reads; .npy, PNG, EXR) or a "
                            "dataset name (hftrace datasets list); default jacksboro")
        p.add_argument("--band", type=positive_int, default=1, help="the raster band (1-based)")
        p.add_argument("--spacing", type=spacing_arg, default=None, metavar="D|DX,DY",
                       help="pixel size of a file without georeferencing, in the unit of its "
                            "heights (default 1: cell units)")
        p.add_argument("--unit", default=None, choices=UNIT_CHOICES,
                       help="the linear unit of --spacing and of the heights of a file "
                            "without a CRS (needed by --curvature); a georeferenced file's "
                            "CRS gives its own")
        p.add_argument("--vertical-scale", type=float, default=1.0,
                       help="factor on the file's heights (e.g. 0.3048 for feet on a metre grid)")
        p.add_argument("--reproject", choices=("utm",), default=None,
                       help="reproject a geographic (degrees) raster to the UTM zone of its "
                            "centre (bilinear); without it such a file is refused")
        p.add_argument("--fill", default=None, metavar="min|VALUE",
                       help="fill the voids (nodata) with the lowest height or VALUE; default: "
                            "voids stay nodata in the outputs and block no ray")
        p.add_argument("--nodata", type=float, default=None, metavar="VALUE",
                       help="the nodata value of a file that declares none (e.g. -9999): "
                            "its samples are voids")
        p.add_argument("--size", type=positive_int, default=None, help="dataset size")
        p.add_argument("--seed", type=int, default=1, help="dataset seed")
        p.add_argument("--param", type=param, action="append", metavar="NAME=VALUE",
                       help="dataset parameter")
        p.add_argument("--algorithm", default=None, help="default: chosen by measurement")
        p.add_argument("--threads", type=positive_int, default=None,
                       help="default: every core in the affinity")
        p.add_argument("--max-distance", type=float, default=None,
                       help="in the unit of the pixel size (metres for a projected DEM and "
                            "jacksboro); default unlimited")
        default = os.path.join(results_dir(kind), kind)
        p.add_argument("--out", default=default,
                       help=f"output path prefix: PREFIX.tif, .png, .exr (--dask: .tif and "
                            f".png only) (default {default})")
        p.add_argument("--no-progress", action="store_true")
        p.add_argument("--dask", default=None, metavar="ADDRESS",
                       help="tile by tile on a Dask cluster (a scheduler address, or local:N "
                            "for N single-threaded local workers); needs --max-distance; "
                            "files are read window by window, so they may exceed memory; "
                            "writes the GeoTIFF and the PNG but no EXR (an EXR is written "
                            "from the whole product in memory)")
        p.add_argument("--chunk", type=positive_int, default=2048,
                       help="--dask: tile side in samples (default 2048)")
        p.add_argument("--worker-memory", default=None, metavar="BYTES",
                       help="--dask local:N: memory limit per worker, e.g. 600MiB")
        if kind == "horizon":
            p.add_argument("--azimuths", default=None,
                           help="comma-separated degrees clockwise from north (default 0)")
        if kind in ("horizon", "shadows", "svf", "openness"):
            _curvature_options(p)
        if kind in ("horizon", "openness"):
            p.add_argument("--units", choices=algos.terrain.ANGLE_UNITS, default="degrees",
                           help="the angles' unit in the files (default degrees; recorded as "
                                "the units tag)")
        if kind == "openness":
            p.add_argument("--kind", choices=("positive", "negative"), default="positive",
                           help="positive: 90 deg minus the mean horizon angle; negative: "
                                "90 deg plus the mean lowest elevation angle (default positive)")
        if kind in ("svf", "openness"):
            p.add_argument("--n-azimuths", type=positive_int, default=None,
                           help="equally spaced azimuths from north (default 16)")
            p.add_argument("--azimuths", default=None, help="comma-separated degrees")
            p.add_argument("--rational", action="store_true",
                           help="nearest rational azimuths: the exact sweep applies")
        if kind in ("horizon", "svf", "shadows", "openness"):
            p.add_argument("--snap-denominator", type=positive_int, default=None, metavar="N",
                           help="snap each azimuth to the nearest rational direction p/q, "
                                "q <= N (the sweep applies); recorded in the tags. Default: "
                                "no snapping")
        if kind == "shadows":
            p.add_argument("--azimuth", type=float, default=315.0,
                           help="the sun's, degrees clockwise from north (default 315, the "
                                "north-west, as gdaldem hillshade)")
            p.add_argument("--elevation", type=float, default=30.0,
                           help="the sun's, degrees above the horizon (default 30)")
        if kind == "viewshed":
            p.add_argument("--observer", action="append", default=[], metavar="X,Y[,HEIGHT]",
                           help="map coordinates in the file's CRS (repeatable); HEIGHT above "
                                "the ground overrides --observer-height")
            p.add_argument("--observer-pixel", action="append", default=[],
                           metavar="COL,ROW[,HEIGHT]",
                           help="a pixel: column from the west edge, row from the north edge, "
                                "the same on every input (repeatable)")
            p.add_argument("--observers", default=None, metavar="CSV",
                           help="a CSV file of x,y[,height] lines (map coordinates)")
            p.add_argument("--observers-pixel", action="store_true",
                           help="--observers holds pixels (col,row[,height])")
            p.add_argument("--observer-height", type=float, default=None,
                           help="above the ground, in the unit of the pixel size (default "
                                "1.75; negative: below the ground)")
            p.add_argument("--target-height", type=float, default=0.0,
                           help="above the ground, in the unit of the pixel size")
            p.add_argument("--mode", "-om", default="normal",
                           choices=algos.terrain.VIEWSHED_MODES,
                           help="normal: visibility; ground: the smallest visible target "
                                "height above the ground; dem: its elevation; observer: the "
                                "smallest observer height that sees the vertex; angle: the "
                                "vertical view angle (degrees). As gdal_viewshed -om")
            p.add_argument("--visible-value", "-vv", type=float, default=None,
                           help="--mode normal: the value of a visible vertex (default 1; "
                                "as gdal_viewshed -vv)")
            p.add_argument("--invisible-value", "-iv", type=float, default=None,
                           help="--mode normal: the value of a hidden vertex (default 0; "
                                "as gdal_viewshed -iv)")
            p.add_argument("--out-of-range-value", "-ov", type=float, default=None,
                           help="the value beyond --max-distance (default 0 in --mode "
                                "normal, nodata in the others; as gdal_viewshed -ov)")
            p.add_argument("--curvature", action="store_true",
                           help="Earth curvature and refraction (as gdal_viewshed, r.viewshed)")
            p.add_argument("--refraction", type=float, default=algos.DEFAULT_REFRACTION,
                           help=f"refraction coefficient (default 1/7 = "
                                f"{algos.DEFAULT_REFRACTION:.5f}, as GDAL and GRASS)")
        p.set_defaults(func=terrain_product, command=kind)
