"""Height fields from files, and the embedded real terrain.

Units. hftrace grids have samples one unit apart and heights in the same unit
(CONVENTIONS.md). A file holds heights in some unit with a horizontal sample spacing in
that same unit (metres, say); the loaders convert:

    H_cells = heights_file * vertical_scale / spacing

* ``spacing``: the horizontal distance between samples, in the unit of the (scaled)
  heights. Default: from the file when it says (GeoTIFF ``ModelPixelScaleTag``),
  otherwise 1, meaning the heights already are in cell units.
* ``vertical_scale``: a factor applied to the file's heights first (exaggeration, or a
  unit change such as 0.3048 for feet to metres). Default 1.

Nodata. The policy is explicit (``nodata_policy``):

* ``"error"`` (default): a NaN, an infinity or a sample equal to ``nodata`` (or to the
  GeoTIFF's GDAL_NODATA tag) raises ValueError naming the file and the first (row, col);
* ``"fill-min"``: such samples become the lowest valid height;
* ``"fill"``: they become ``fill_value``.

Images. 8- and 16-bit grayscale PNG and JPEG (Pillow) are read as integer heights 0..255
or 0..65535; colour images are refused rather than guessed at. OpenEXR files must have
one channel, or name it with ``channel``.
"""
from __future__ import annotations

import hashlib
import math
import os
from dataclasses import dataclass, field

import numpy as np

from .cache import cached_array
from .fields import det_cos

__all__ = ["HeightField", "LoaderError", "load_file", "jacksboro", "resample_bilinear", "EARTH_RADIUS_M",
           "NODATA_POLICIES"]

#: IUGG mean Earth radius, for degrees -> metres.
EARTH_RADIUS_M = 6371008.8
NODATA_POLICIES = ("error", "fill-min", "fill")
_GEOTIFF_PIXEL_SCALE = 33550
_GDAL_NODATA = 42113


class LoaderError(ValueError):
    """A file that cannot be used as a height field; the message names the file or the
    parameter."""


@dataclass
class HeightField:
    """Heights in cell units plus what they are and where they came from."""

    heights: np.ndarray  # float32, (rows, cols)
    name: str
    spacing: float = 1.0  # real distance per cell, in `unit`
    unit: str = "cell"
    params: dict = field(default_factory=dict)

    @property
    def shape(self):
        return self.heights.shape

    @property
    def checksum(self) -> str:
        """SHA-256 of the float32 bytes (C order, little-endian)."""
        data = np.ascontiguousarray(self.heights, dtype="<f4")
        return hashlib.sha256(data.tobytes()).hexdigest()


def _apply_nodata(heights, path, nodata, policy, fill_value):
    if policy not in NODATA_POLICIES:
        raise ValueError(f"nodata_policy: expected one of {NODATA_POLICIES}, got {policy!r}")
    bad = ~np.isfinite(heights)
    if nodata is not None:
        bad |= heights == nodata
    if not bad.any():
        return heights
    if policy == "error":
        row, col = (int(v) for v in np.argwhere(bad)[0])
        raise ValueError(
            f"{path}: {int(bad.sum())} nodata/non-finite samples, the first at (row {row}, "
            f"col {col}) = {heights[row, col]}; choose nodata_policy='fill-min' or 'fill'")
    if policy == "fill-min":
        if bad.all():
            raise ValueError(f"{path}: every sample is nodata; nothing to fill with")
        value = heights[~bad].min()
    else:
        if fill_value is None or not math.isfinite(fill_value):
            raise ValueError("fill_value: nodata_policy='fill' needs a finite fill_value")
        value = fill_value
    out = heights.copy()
    out[bad] = value
    return out


def _read_tiff(path, read_data=True):
    import tifffile

    with tifffile.TiffFile(path) as tif:
        page = tif.pages[0]
        data = page.asarray() if read_data else None
        tags = page.tags
        spacing = nodata = None
        if _GEOTIFF_PIXEL_SCALE in tags:
            sx, sy = tags[_GEOTIFF_PIXEL_SCALE].value[:2]
            if not math.isclose(sx, sy, rel_tol=1e-6):
                raise LoaderError(f"{path}: pixel scale {sx} x {sy} is not square; resample it "
                                 "first or pass spacing explicitly")
            spacing = float(sx)
        if _GDAL_NODATA in tags:
            text = str(tags[_GDAL_NODATA].value).strip().strip("\x00")
            nodata = float(text) if text else None
    return data, spacing, nodata


def _read_image(path):
    from PIL import Image

    with Image.open(path) as image:
        if image.mode not in ("L", "I;16", "I;16B", "I;16L", "I"):
            raise LoaderError(f"{path}: image mode {image.mode!r} is not 8- or 16-bit grayscale")
        return np.asarray(image)


def _read_exr(path, channel):
    import OpenEXR

    with OpenEXR.File(str(path)) as f:
        channels = f.channels()
        if channel is None:
            if len(channels) != 1:
                raise LoaderError(f"{path}: {len(channels)} channels ({', '.join(channels)}); "
                                 "name one with channel=")
            channel = next(iter(channels))
        if channel not in channels:
            raise LoaderError(f"channel: {channel!r} not in {path} ({', '.join(channels)})")
        return np.array(channels[channel].pixels)


def load_file(path, *, spacing=None, vertical_scale=1.0, nodata=None, nodata_policy="error",
              fill_value=None, key=None, channel=None) -> HeightField:
    """Read a height field from ``.npy``, ``.npz``, GeoTIFF (``.tif``/``.tiff``),
    8/16-bit grayscale ``.png``/``.jpg``/``.jpeg`` or single-channel ``.exr``.

    See the module docstring for units and the nodata policy. Raises ValueError naming
    the file (or the parameter) for unreadable files, wrong shapes and bad samples.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"path: {path} does not exist or is not a file")
    ext = os.path.splitext(path)[1].lower()
    mapped = _mapped(path, ext, spacing, vertical_scale, nodata, nodata_policy)
    if mapped is not None:
        return mapped
    file_spacing = file_nodata = None
    try:
        if ext == ".npy":
            data = np.load(path, allow_pickle=False)
        elif ext == ".npz":
            with np.load(path, allow_pickle=False) as archive:
                names = archive.files
                if key is None:
                    key = next((k for k in ("heights", "elevation") if k in names),
                               names[0] if len(names) == 1 else None)
                if key not in names:
                    raise LoaderError(f"key: {path} holds {', '.join(names)}; name one with key=")
                data = archive[key]
        elif ext in (".tif", ".tiff"):
            data, file_spacing, file_nodata = _read_tiff(path)
        elif ext in (".png", ".jpg", ".jpeg"):
            data = _read_image(path)
        elif ext == ".exr":
            data = _read_exr(path, channel)
        else:
            raise LoaderError(f"path: unknown extension {ext!r} of {path}; expected .npy, .npz, "
                             ".tif, .tiff, .png, .jpg, .jpeg or .exr")
    except LoaderError:
        raise
    except Exception as exc:  # a damaged file: say which one and what the reader said
        raise LoaderError(f"{path}: cannot be read as {ext} ({type(exc).__name__}: {exc})") from None
    data = np.asarray(data)
    if data.ndim != 2:
        raise ValueError(f"{path}: expected a 2D height array, got shape {data.shape}")
    if data.shape[0] < 2 or data.shape[1] < 2:
        raise ValueError(f"{path}: a height field needs at least 2 x 2 samples, got {data.shape}")
    if data.dtype.kind not in "fiu":
        raise ValueError(f"{path}: heights must be real numbers, got dtype {data.dtype}")
    heights = _apply_nodata(data.astype(np.float64), path,
                            nodata if nodata is not None else file_nodata, nodata_policy,
                            fill_value)
    if spacing is None:
        spacing = file_spacing if file_spacing is not None else 1.0
    if not (math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing: must be a positive finite number, got {spacing}")
    if not (math.isfinite(vertical_scale) and vertical_scale != 0):
        raise ValueError(f"vertical_scale: must be a non-zero finite number, got {vertical_scale}")
    cells = np.ascontiguousarray(heights * vertical_scale / spacing, dtype=np.float32)
    return HeightField(cells, os.path.basename(path), float(spacing), "file unit",
                       dict(path=path, spacing=spacing, vertical_scale=vertical_scale,
                            nodata=nodata, nodata_policy=nodata_policy))


def _mapped(path, ext, spacing, vertical_scale, nodata, policy):
    """The file's heights memory-mapped read-only, without a copy, where nothing needs
    converting: a 2D C-ordered native float32 ``.npy`` or uncompressed GeoTIFF, no
    nodata value, all finite, ``spacing`` (given or from the file) 1 and
    ``vertical_scale`` 1 (heights already in cells, as ``hftrace`` writes them). Else
    None: the general path reads and converts in memory."""
    if ext not in (".npy", ".tif", ".tiff") or vertical_scale != 1.0 or nodata is not None:
        return None
    try:
        if ext == ".npy":
            data, file_spacing, file_nodata = np.load(path, mmap_mode="r", allow_pickle=False), None, None
        else:
            import tifffile

            _, file_spacing, file_nodata = _read_tiff(path, read_data=False)
            data = tifffile.memmap(path, mode="r")
    except Exception:  # compressed, tiled or damaged: the general path says what is wrong
        return None
    use_spacing = spacing if spacing is not None else (file_spacing or 1.0)
    if (data.ndim != 2 or data.dtype != np.dtype("=f4") or not data.flags.c_contiguous
            or file_nodata is not None or use_spacing != 1.0 or min(data.shape) < 2):
        return None
    step = max(1, (1 << 20) // data.shape[1])
    for r0 in range(0, data.shape[0], step):  # bounded temporaries
        if not np.isfinite(data[r0:r0 + step]).all():
            if policy != "error":
                return None  # filling needs a copy: the general path
            bad = ~np.isfinite(data[r0:r0 + step])
            row, col = (int(v) for v in np.argwhere(bad)[0])
            raise ValueError(f"{path}: non-finite sample at (row {row + r0}, col {col}) = "
                             f"{data[row + r0, col]}; choose nodata_policy='fill-min' or 'fill'")
    return HeightField(data, os.path.basename(path), 1.0, "file unit",
                       dict(path=path, spacing=1.0, vertical_scale=1.0, nodata=None,
                            nodata_policy=policy, memory_mapped=True))


def resample_bilinear(heights: np.ndarray, rows: int, cols: int) -> np.ndarray:
    """Bilinear resampling onto ``rows x cols`` samples spanning the same extent (corner
    samples kept), in float64 basic arithmetic (deterministic)."""
    src = np.asarray(heights, dtype=np.float64)
    r0, c0 = src.shape

    def axis(n_out, n_in):
        pos = np.arange(n_out, dtype=np.float64) * ((n_in - 1) / (n_out - 1) if n_out > 1 else 0.0)
        lo = np.minimum(np.floor(pos).astype(np.int64), n_in - 2 if n_in > 1 else 0)
        return lo, pos - lo

    jr, fr = axis(rows, r0)
    ic, fc = axis(cols, c0)
    top = np.take(src[jr], ic, axis=1) * (1 - fc) + np.take(src[jr], ic + 1, axis=1) * fc
    bottom = np.take(src[jr + 1], ic, axis=1) * (1 - fc) + np.take(src[jr + 1], ic + 1, axis=1) * fc
    return top * (1 - fr)[:, None] + bottom * fr[:, None]


def jacksboro(size=None, vertical_scale=1.0, *, use_cache=True, cache_dir=None) -> HeightField:
    """The Jacksboro fault DEM from matplotlib's sample data (``jacksboro_fault_dem.npz``:
    344 x 403 int16 elevations in metres, 3 arc-second spacing, about 36.45-36.73 N,
    84.08-84.41 W).

    Conversion: the spacing in degrees becomes metres on a sphere of radius
    6,371,008.8 m, the east-west spacing scaled by cos(latitude) at the centre (about
    74.4 m east-west, 92.7 m north-south). The field is then resampled bilinearly onto
    square cells: by default at the east-west spacing (about 403 x 428 samples); with
    ``size`` given, the longer side gets ``size`` samples. Rows are flipped so that y
    (row index) increases northward. Heights in cells: metres * vertical_scale /
    cell spacing in metres; ``spacing`` in the result is that cell spacing in metres.
    """
    from matplotlib import cbook

    with cbook.get_sample_data("jacksboro_fault_dem.npz") as dem:
        elevation = np.asarray(dem["elevation"], dtype=np.float64)
        dx_deg, dy_deg = float(dem["dx"]), float(dem["dy"])
        lat_a, lat_b = float(dem["ymin"]), float(dem["ymax"])
    north_first = lat_a > lat_b
    if north_first:
        elevation = elevation[::-1]
    lat_centre = (lat_a + lat_b) / 2
    metres_per_degree = math.pi / 180 * EARTH_RADIUS_M
    dy_m = dy_deg * metres_per_degree
    dx_m = dx_deg * metres_per_degree * float(det_cos(lat_centre * math.pi / 180))
    rows0, cols0 = elevation.shape
    extent_x, extent_y = (cols0 - 1) * dx_m, (rows0 - 1) * dy_m
    if size is None:
        cell = dx_m
    else:
        size = int(size)
        if not 2 <= size <= 8192:
            raise ValueError(f"size: {size} outside [2, 8192]")
        cell = max(extent_x, extent_y) / (size - 1)
    cols = int(round(extent_x / cell)) + 1
    rows = int(round(extent_y / cell)) + 1

    def build():
        resampled = resample_bilinear(elevation, rows, cols)
        return np.ascontiguousarray(resampled * vertical_scale / cell, dtype=np.float32)

    description = dict(kind="embedded", name="jacksboro", size=size,
                       vertical_scale=vertical_scale, version=1)
    heights = cached_array(description, build, use_cache=use_cache, directory=cache_dir)
    return HeightField(heights, "jacksboro", cell, "m",
                       dict(size=size, vertical_scale=vertical_scale, dx_m=dx_m, dy_m=dy_m,
                            north="+y",  # rows run north: the terrain products flip them
                            source="matplotlib sample data jacksboro_fault_dem.npz"))


class LazyRaster:
    """A raster file read window by window: what ``dask.array.from_array`` wraps so that
    each task reads only its own chunk. Pickles as its path (workers open the file
    themselves); heights come out as float32 in cells (times ``scale``)."""

    def __init__(self, path, scale=1.0):
        self.path = os.fspath(path)
        self.scale = float(scale)
        probe = self._open()
        if probe.ndim != 2:
            raise ValueError(f"{self.path}: expected a 2D height array, got shape {probe.shape}")
        if probe.dtype.kind not in "fiu":
            raise ValueError(f"{self.path}: heights must be real numbers, got dtype {probe.dtype}")
        self.shape = tuple(probe.shape)
        self.ndim = 2
        self.dtype = np.dtype(np.float32)

    def _open(self):
        ext = os.path.splitext(self.path)[1].lower()
        if ext == ".npy":
            return np.load(self.path, mmap_mode="r", allow_pickle=False)
        if ext in (".tif", ".tiff"):
            import tifffile

            try:
                return tifffile.memmap(self.path, mode="r")
            except Exception as exc:
                raise ValueError(f"{self.path}: cannot be memory-mapped ({exc}); lazy reading "
                                 "takes uncompressed, untiled GeoTIFF or .npy") from None
        raise ValueError(f"path: {self.path}: lazy reading takes .npy or uncompressed GeoTIFF")

    def __getitem__(self, key):
        window = np.asarray(self._open()[key], dtype=np.float64) * self.scale
        if not np.isfinite(window).all():
            bad = np.argwhere(~np.isfinite(window))[0]
            raise ValueError(f"{self.path}: non-finite sample in window {key} at offset "
                             f"{tuple(int(v) for v in bad)}")
        return window.astype(np.float32)

    def __getstate__(self):
        return {"path": self.path, "scale": self.scale, "shape": self.shape}

    def __setstate__(self, state):
        self.path, self.scale, self.shape = state["path"], state["scale"], state["shape"]
        self.ndim, self.dtype = 2, np.dtype(np.float32)


def open_lazy(path, *, chunks=2048, spacing=None, vertical_scale=1.0) -> HeightField:
    """A HeightField whose heights are a lazy dask array over the file (``.npy`` or
    uncompressed GeoTIFF), read chunk by chunk where it is computed: for fields larger
    than memory (``algos.horizon`` and friends take it and work tile by tile)."""
    import dask.array as da

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"path: {path} does not exist or is not a file")
    ext = os.path.splitext(path)[1].lower()
    file_spacing = None
    if ext in (".tif", ".tiff"):
        _, file_spacing, _ = _read_tiff(path, read_data=False)
    if spacing is None:
        spacing = file_spacing if file_spacing is not None else 1.0
    if not (math.isfinite(spacing) and spacing > 0):
        raise ValueError(f"spacing: must be a positive finite number, got {spacing}")
    raster = LazyRaster(path, scale=vertical_scale / spacing)
    heights = da.from_array(raster, chunks=chunks, asarray=False, lock=False, fancy=False)
    return HeightField(heights, os.path.basename(path), float(spacing), "file unit",
                       dict(path=path, spacing=spacing, vertical_scale=vertical_scale,
                            lazy=True, chunks=chunks))
