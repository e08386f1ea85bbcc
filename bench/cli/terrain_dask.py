"""``hftrace horizon|shadows|svf|viewshed SOURCE --dask ADDRESS``: terrain products tile by
tile on a Dask cluster, for fields larger than the memory of any one worker.

The source is read lazily (``datasets_gen.open_lazy``: each task memory-maps the file
and copies its own window), the products run with a halo of ``max_distance``
(``algos.tiled``), and every finished tile is written straight into a float32 GeoTIFF
(uncompressed, memory-mapped for writing) by the worker that computed it; nothing of
field size passes through the driver. A small PNG preview is read back by striding.
"""
from __future__ import annotations

import dataclasses
import os
import time

import numpy as np

import algos
import datasets_gen

__all__ = ["TiffTarget", "run_product", "open_source"]


class TiffTarget:
    """A ``dask.array.store`` target: an existing uncompressed float32 GeoTIFF that each
    write opens for update (pickles as its path, so any worker can write its tile)."""

    def __init__(self, path):
        self.path = os.fspath(path)

    def __setitem__(self, key, value):
        import tifffile

        image = tifffile.memmap(self.path, mode="r+")
        image[key] = value
        image.flush()
        del image


def create_tiff(path, shape, spacing=None):
    """An uncompressed float32 GeoTIFF of ``shape``, filled with NaN (the pixel scale tag
    when ``spacing`` is known)."""
    import tifffile

    extratags = [(33550, "d", 3, (float(spacing), float(spacing), 0.0), False)] if spacing else []
    image = tifffile.memmap(path, shape=shape, dtype=np.float32, extratags=extratags)
    step = max(1, (1 << 22) // shape[1])
    for r0 in range(0, shape[0], step):
        image[r0:r0 + step] = np.nan
    image.flush()
    del image


def preview_png(tif_path, png_path, cmap, vmin, vmax, max_side=2048):
    """A colour-mapped PNG of a (possibly huge) GeoTIFF, read with a stride."""
    import tifffile
    from matplotlib import colormaps
    from PIL import Image

    image = tifffile.memmap(tif_path, mode="r")
    stride = max(1, -(-max(image.shape) // max_side))
    data = np.asarray(image[::stride, ::stride], dtype=np.float32)
    lo = float(np.nanmin(data)) if vmin is None else vmin
    hi = float(np.nanmax(data)) if vmax is None else vmax
    norm = (data - lo) / (hi - lo) if hi > lo else np.zeros_like(data)
    rgba = colormaps[cmap](np.clip(np.nan_to_num(norm), 0, 1))
    Image.fromarray(np.round(rgba[..., :3] * 255).astype(np.uint8)).save(png_path)
    return data


def open_source(source, chunk, size=None, seed=1, params=None):
    """A HeightField with lazy (dask) heights: a file read window by window, or a
    dataset generated in memory and then chunked."""
    import dask.array as da

    if os.path.exists(source):
        return datasets_gen.open_lazy(source, chunks=chunk)
    hf = datasets_gen.load(source, size=size, seed=seed, **(params or {}))
    return dataclasses.replace(hf, heights=da.from_array(np.asarray(hf.heights), chunks=chunk))


def run_product(kind, hf, out, address, *, max_distance, azimuths=(0.0,), n_azimuths=16,
                rational=False, azimuth=315.0, elevation=30.0, observers=(), observer_height=1.75,
                target_height=0.0, curvature=False, refraction=0.13, algorithm=None,
                worker_memory=None, echo=print):
    """Compute one product on the cluster at ``address`` (``local:N``: a LocalCluster of
    N single-threaded workers, each limited to ``worker_memory``); write ``out``.tif
    (north-up) and ``out``.png. Returns the paths written."""
    import dask.array as da

    from ..sweep import dask_client

    if max_distance is None:
        raise ValueError("--max-distance: a tiled (dask) product needs a finite distance "
                         "(it is the tiles' halo)")
    spacing = hf.spacing if hf.unit != "cell" else None
    flip = (hf.params or {}).get("north") == "+y"
    common = dict(algorithm=algorithm, threads=1)  # one thread per worker
    if kind == "horizon":
        products = {f"horizon_az{a:g}": (da.degrees(algos.horizon(hf, [a], max_distance, **common)[0]),
                                         "magma", None, None) for a in azimuths}
    elif kind == "svf":
        products = {"svf": (algos.sky_view_factor(hf, n_azimuths, max_distance, rational=rational,
                                                  **common), "cividis", 0.0, 1.0)}
    elif kind == "shadows":
        products = {"shadows": (algos.shadows(hf, azimuth, elevation, max_distance=max_distance,
                                              **common), "gray_r", 0.0, 1.0)}
    else:
        rows, cols = hf.shape
        obs = list(observers) or [((cols - 1) / 2, (rows - 1) / 2)]
        seen = algos.viewshed(hf, obs, observer_height, target_height, max_distance,
                              curvature=curvature, refraction=refraction, **common)
        products = {"viewshed": (seen, "Greens", 0.0, float(len(obs)))}
    client, cluster = dask_client(address, memory_limit=worker_memory)
    paths = []
    try:
        for name, (lazy, cmap, lo, hi) in products.items():
            prefix = out if len(products) == 1 else f"{out}_{name}"
            lazy = lazy.astype(np.float32)
            if flip:
                lazy = lazy[::-1]  # files are written north-up
            create_tiff(prefix + ".tif", lazy.shape, spacing)
            start = time.perf_counter()
            da.store(lazy, TiffTarget(prefix + ".tif"), lock=False, compute=True)
            seconds = time.perf_counter() - start
            shown = preview_png(prefix + ".tif", prefix + ".png", cmap, lo, hi)
            finite = shown[np.isfinite(shown)]
            echo(f"{name}: {hf.name} {hf.shape[0]}x{hf.shape[1]} on {address} in {seconds:.1f} s "
                 f"({lazy.numblocks[0] * lazy.numblocks[1]} tiles), preview min "
                 f"{finite.min():.4g}, mean {finite.mean():.4g}, max {finite.max():.4g} -> "
                 f"{prefix}.tif, {prefix}.png")
            paths += [prefix + ".tif", prefix + ".png"]
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return paths
