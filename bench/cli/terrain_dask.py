"""``hftrace horizon|shadows|svf|openness|viewshed SOURCE --dask ADDRESS``: terrain products tile by
tile on a Dask cluster, for fields larger than the memory of any one worker.

The source is read lazily (``datasets_gen.open_lazy``: each task reads its own window
through rasterio), the products run with a halo of ``max_distance`` (``algos.terrain.tiled``),
and every finished tile is written straight into the output GeoTIFF by the worker that
computed it (``datasets_gen.raster.create_product`` and ``write_window``, one
``distributed.Lock`` per file, since GDAL rewrites whole compressed tiles); nothing of
field size passes through the driver. The file has the input's grid, CRS, geotransform
and nodata, as in memory; a PNG preview is drawn from a decimated read. No EXR is
written: the OpenEXR writer takes the whole product as one array in memory, which this
path never holds (the GeoTIFF has the same values; in memory the EXR is the float32 of
the GeoTIFF's bands). The files' tags are the in-memory ones, but for ``paths`` (each
azimuth's algorithm, a statistic of an in-memory call; ``--snap-denominator`` is
refused here).
"""
from __future__ import annotations

import math
import os
import time

import numpy as np

import algos
from algos.validate import check_length

from .terrain_field import load_terrain
from .terrain_options import (
    azimuths_option,
    check_options,
    observers,
    observers_tag,
    output_prefix,
    product_options,
)

__all__ = ["GeoTiffTarget", "run_product", "terrain_product_dask"]


class GeoTiffTarget:
    """A ``dask.array.store`` target: band ``band`` of an existing GeoTIFF that each write
    opens for update (pickles as its path, so any worker can write its tile)."""

    def __init__(self, path, band=1):
        self.path = os.fspath(path)
        self.band = band

    def __setitem__(self, key, value):
        from datasets_gen.raster import write_window

        rows, cols = key
        write_window(self.path, value, rows.start or 0, cols.start or 0, band=self.band)


def preview_png(tif_path, png_path, *, product, units, params, cmap, border=None,
                max_side=2048):
    """A PNG of band 1 of a (possibly huge) GeoTIFF, read decimated to at most
    ``max_side`` samples a side; returns the array drawn (NaN at nodata)."""
    import rasterio

    from datasets_gen.preview import product_png

    with rasterio.open(tif_path) as src:
        stride = max(1, -(-max(src.height, src.width) // max_side))
        shape = (-(-src.height // stride), -(-src.width // stride))
        data = src.read(1, out_shape=shape, masked=True).astype(np.float64).filled(np.nan)
    product_png(png_path, data, None, product=product, units=units, params=params,
                cmap=cmap, border=border)
    return data


def run_product(kind, field, out, address, *, max_distance, azimuths=(0.0,), n_azimuths=16,
                rational=False, azimuth=315.0, elevation=30.0, observers=(),
                observer_height=1.75, target_height=0.0, curvature=False,
                refraction=algos.DEFAULT_REFRACTION, algorithm=None, worker_memory=None,
                params=None, openness_kind="positive", units="degrees", echo=print):
    """Compute one product of the lazy ``field`` on the cluster at ``address``
    (``local:N``: a LocalCluster of N single-threaded workers, each limited to
    ``worker_memory``); write ``out``.tif (a band per azimuth for horizons) and
    ``out``.png, no EXR (module docstring). ``observers`` are ``(col, row, height or
    None)`` in grid coordinates. A failed run removes the GeoTIFF it began. Returns the
    paths written."""
    import dask.array as da
    from distributed import Lock

    from datasets_gen.raster import create_product

    from ..sweep_dask import close_client, dask_client

    if max_distance is not None:
        check_length(max_distance, "max_distance")  # NaN, negative: the in-memory message
    if max_distance is None or not math.isfinite(max_distance):
        raise ValueError("--max-distance: a tiled (dask) product needs a finite distance "
                         "(it is the tiles' halo)"
                         + ("" if max_distance is None else f", got {max_distance}"))
    common = dict(algorithm=algorithm, threads=1)  # one thread per worker
    curve = dict(curvature=curvature, refraction=refraction)
    band_names = border = None
    if kind == "horizon":
        layers = [algos.horizon(field, [a], max_distance, units=units, **curve,
                                **common)[0] for a in azimuths]
        product, cmap = "horizon", "magma"
        border = -90.0 if units == "degrees" else -math.pi / 2
        band_names = [f"azimuth {a:g}" for a in azimuths]
    elif kind == "svf":
        layers = [algos.sky_view_factor(field, n_azimuths, max_distance, rational=rational,
                                        **curve, **common)]
        product, units, cmap = "sky_view_factor", "1", "cividis"
    elif kind == "openness":
        layers = [algos.openness(field, openness_kind, n_azimuths, max_distance,
                                 rational=rational, units=units, **curve, **common)]
        product, cmap = f"openness_{openness_kind}", "cividis"
    elif kind == "shadows":
        layers = [algos.shadows(field, azimuth, elevation, max_distance=max_distance,
                                **curve, **common)]
        product, units, cmap = "shadows", "1 = in shadow", "gray_r"
    else:
        rows, cols = field.shape
        obs = list(observers) or [((cols - 1) / 2, (rows - 1) / 2, None)]
        heights = [observer_height if h is None else h for _, _, h in obs]
        count = None
        for height in dict.fromkeys(heights):
            group = [(c, r) for (c, r, _), h in zip(obs, heights) if h == height]
            seen = algos.viewshed(field, group, height, target_height, max_distance,
                                  curvature=curvature, refraction=refraction, **common)
            seen = seen.astype(np.uint16)
            count = seen if count is None else count + seen
        layers = [count > 0 if len(obs) == 1 else count]
        product = "viewshed"
        units = "1 = visible" if len(obs) == 1 else "observers that see the vertex"
        cmap = "Greens"
    client, cluster = dask_client(address, memory_limit=worker_memory)
    path = out + ".tif"
    created = False
    try:
        dtype = np.float32 if layers[0].dtype.kind == "f" else layers[0].dtype
        create_product(path, field, dtype=dtype, product=product, units=units, params=params,
                       count=len(layers))
        created = True
        start = time.perf_counter()
        lock = Lock(os.path.abspath(path))
        # voids (NaN heights of a lazy file, or the field's mask) are written as nodata
        voids = field.nodata_mask if field.nodata_mask is not None else da.isnan(field.heights)
        for band, lazy in enumerate(layers, start=1):
            lazy = da.where(voids, np.nan, lazy.astype(np.float32))
            if field.transform is None and field.north == "+y":
                # a field without a geotransform is written north-up (as the in-memory
                # writer does); a georeferenced one on its own grid, rows as stored
                lazy = lazy[::-1]
            da.store(lazy, GeoTiffTarget(path, band), lock=lock, compute=True)
        seconds = time.perf_counter() - start
    except BaseException:
        # a failed run leaves no half-written GeoTIFF (the in-memory path writes nothing)
        if created and os.path.exists(path):
            os.remove(path)
        raise
    finally:
        close_client(client, cluster)
    shown = preview_png(path, out + ".png", product=product, units=units, params=params or {},
                        cmap=cmap, border=border)
    if band_names:
        import rasterio

        with rasterio.open(path, "r+") as dst:
            for k, name in enumerate(band_names, start=1):
                dst.set_band_description(k, name)
    finite = shown[np.isfinite(shown)]
    summary = (f"preview min {finite.min():.4g}, mean {finite.mean():.4g}, max "
               f"{finite.max():.4g}" if finite.size else "no valid vertex in the preview")
    tiles = layers[0].numblocks[0] * layers[0].numblocks[1]
    echo(f"{product} ({units}): {field.name} {field.shape[0]}x{field.shape[1]} on {address} "
         f"in {seconds:.1f} s ({tiles} tiles), {summary} -> {path}, {out}.png")
    return [path, out + ".png"]


def terrain_product_dask(args):
    """``--dask``: the command's product tile by tile (:func:`run_product`)."""
    check_options(args)
    args.out = output_prefix(args)
    field = load_terrain(args, lazy_chunks=args.chunk)
    kind = args.command
    options = dict(max_distance=args.max_distance, algorithm=args.algorithm,
                   worker_memory=args.worker_memory, params=product_options(args, field))
    if getattr(args, "snap_denominator", None) is not None:
        raise ValueError("--snap-denominator: not available with --dask (each tile would "
                         "record its own paths); snap the azimuths with "
                         "algos.terrain.snap_azimuths and pass them with --azimuths")
    if kind in ("horizon", "openness"):
        options["units"] = args.units
    if kind == "horizon":
        options["azimuths"] = azimuths_option(args) or [0.0]
    elif kind == "svf":
        if azimuths_option(args):
            raise ValueError("--azimuths: not available with --dask for svf; use --n-azimuths")
        options.update(n_azimuths=args.n_azimuths, rational=args.rational)
    elif kind == "openness":
        if azimuths_option(args):
            raise ValueError("--azimuths: not available with --dask for openness; use "
                             "--n-azimuths")
        options.update(n_azimuths=args.n_azimuths, rational=args.rational,
                       openness_kind=args.kind)
    elif kind == "shadows":
        options.update(azimuth=args.azimuth, elevation=args.elevation)
    else:
        obs = observers(args, field)
        options["params"]["observers"] = observers_tag(obs, field)  # as in memory
        options.update(observers=obs, observer_height=args.observer_height,
                       target_height=args.target_height, curvature=args.curvature,
                       refraction=args.refraction)
    if kind != "viewshed":
        options.update(curvature=args.curvature, refraction=args.refraction)
    os.makedirs(os.path.dirname(args.out) or ".", exist_ok=True)
    run_product(kind, field, args.out, args.dask, **options)
    return 0
