"""Height fields from files, and the embedded real terrain.

Units. A height field's heights are in the same linear unit as its pixel size
(docs/CONVENTIONS.md, "Grid and heights"). Georeferenced rasters (GeoTIFF, VRT and every
other format GDAL reads, through :mod:`datasets_gen.raster`) carry their pixel size,
CRS, orientation and nodata; the other files (``.npy``, ``.npz``, PNG, JPEG, OpenEXR)
take ``spacing`` (default 1: cell units) and their heights as they are, times
``vertical_scale`` (a unit change such as 0.3048 for feet over a metre grid, or an
exaggeration). Before this version the loaders divided heights by the spacing (cell
units); they no longer do: the products convert (see docs/gis.md, "Map units").

Nodata. The policy is explicit (``nodata_policy``):

* ``"void"`` (default): NaN, infinities and samples equal to ``nodata`` (or to the
  raster's own nodata, or masked by it) are voids: NaN in the heights, True in the
  field's ``nodata_mask``. The terrain products accept them (:mod:`algos.terrain`,
  "Voids"); first hits need a filled field.
* ``"error"``: a void raises ValueError naming the file and the first (row, col);
* ``"fill-min"``: voids become the lowest valid height;
* ``"fill"``: they become ``fill_value``.

Images. 8- and 16-bit grayscale PNG and JPEG (Pillow) are read as integer heights 0..255
or 0..65535; colour images are refused rather than guessed at. OpenEXR files must have
one channel, or name it with ``channel``.
"""
from __future__ import annotations

import math
import os
import warnings

import numpy as np

from algos.field import HeightField
from algos.georef import IUGG_MEAN_EARTH_RADIUS_M, check_crs, check_nodata, unit_name
from algos.validate import check_spacing

from .cache import cached_array
from .fields import det_cos
from .raster import LazyRaster, _refuse, is_line, read_raster, thicken_line, too_small

__all__ = ["HeightField", "LoaderError", "load_file", "jacksboro", "resample_bilinear",
           "NODATA_POLICIES", "open_lazy", "LazyRaster", "RASTER_EXTENSIONS",
           "COMMON_NODATA", "undeclared_nodata"]

NODATA_POLICIES = ("void", "error", "fill-min", "fill")
#: Values that DEM tools write for "no data" (ESRI and GDAL's -9999, -99999, the int16
#: extremes of SRTM-style files, float32's lowest value): a file that holds one as its
#: lowest height without declaring it most likely has undeclared voids.
COMMON_NODATA = (-9999.0, -99999.0, -32768.0, -32767.0, float(np.finfo(np.float32).min))
#: Extensions read through rasterio (GDAL); any other GDAL format can be read with
#: :func:`datasets_gen.raster.read_raster` directly.
RASTER_EXTENSIONS = (".tif", ".tiff", ".vrt", ".img", ".asc", ".hgt", ".nc", ".bil", ".dt0",
                     ".dt1", ".dt2", ".jp2")


class LoaderError(ValueError):
    """A file that cannot be used as a height field; the message names the file or the
    parameter."""


def _apply_nodata(heights, path, mask, policy, fill_value):
    """(heights, mask) after the nodata policy: voids NaN and masked ("void"), an error,
    or filled (mask None)."""
    if policy not in NODATA_POLICIES:
        raise ValueError(f"nodata_policy: expected one of {NODATA_POLICIES}, got {policy!r}")
    if mask is None or not mask.any():
        return heights, None
    if policy == "void":
        if mask.all():
            raise ValueError(f"{path}: every sample is nodata")
        out = heights if heights.dtype.kind == "f" else heights.astype(np.float32)
        out = np.array(out, copy=True)
        out[mask] = np.nan
        return out, mask
    if policy == "error":
        row, col = (int(v) for v in np.argwhere(mask)[0])
        raise ValueError(
            f"{path}: {int(mask.sum())} nodata/non-finite samples, the first at (row {row}, "
            f"col {col}) = {heights[row, col]}; choose nodata_policy='void' (the default), "
            "'fill-min' or 'fill'")
    if policy == "fill-min":
        if mask.all():
            raise ValueError(f"{path}: every sample is nodata; nothing to fill with")
        value = heights[~mask].min()
    else:
        if fill_value is None or not math.isfinite(fill_value):
            raise ValueError("fill_value: nodata_policy='fill' needs a finite fill_value")
        value = fill_value
    out = np.array(heights, dtype=np.float32 if heights.dtype != np.float64 else np.float64)
    out[mask] = value
    return out, None


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


def load_file(path, *, spacing=None, vertical_scale=1.0, nodata=None, nodata_policy="void",
              fill_value=None, key=None, channel=None, band=1, reproject=None,
              unit=None, lines=False) -> HeightField:
    """Read a height field from a raster GDAL reads (``.tif``/``.tiff``/``.vrt`` and the
    other :data:`RASTER_EXTENSIONS`, through :func:`datasets_gen.raster.read_raster`),
    ``.npy``, ``.npz``, 8/16-bit grayscale ``.png``/``.jpg``/``.jpeg`` or single-channel
    ``.exr``.

    Parameters
    ----------
    path : str or path-like
    spacing : float or (dx, dy), optional
        Pixel size of a file without georeferencing, in the unit of its heights (default
        1: cell units). A georeferenced raster's own pixel size is used (giving one
        raises).
    vertical_scale : float
        Factor on the heights (a unit change, or exaggeration).
    nodata : float, optional
        A nodata value for a file that declares none. It must be a value of the file's
        sample type (-9999 on uint8 is refused) and, for a raster that declares one,
        equal to it; both refusals name the two values.
    nodata_policy : {"void", "error", "fill-min", "fill"}
        See the module docstring; default "void".
    fill_value : float, optional
        For ``nodata_policy="fill"``.
    key, channel : str, optional
        The array of an ``.npz``, the channel of an ``.exr``.
    band : int
        1-based band of a raster.
    reproject : None or "utm"
        A geographic raster is refused (None) or reprojected to UTM.
    unit : str, optional
        The linear unit of ``spacing`` and of the heights of a file without a CRS (one of
        ``algos.georef.LINEAR_UNITS``: "m", "km", "ft", "US survey foot", or an alias
        such as "metre"). Default none: cell units, or "map unit" with a ``spacing``,
        which curvature refuses. A georeferenced file's CRS gives its unit; a ``unit``
        that contradicts it raises.
    lines : bool
        Accept a one-row or one-column file (a line, which only :func:`algos.viewshed`
        takes): the field holds the line twice, as two rows (columns), and
        ``params["line"]`` gives the file's shape and the rows and columns of the field
        that are its own samples (:func:`datasets_gen.raster.thicken_line`). Default
        False: such a file raises (a height field needs 2 x 2 samples).

    Returns
    -------
    HeightField
        Heights in the unit of the pixel size, float32 (a ``.npy`` of C-ordered float32
        that needs no conversion is memory-mapped read-only, not copied).

    Raises
    ------
    ValueError
        Naming the file or the parameter: unreadable files, wrong shapes, voids under
        ``nodata_policy="error"``, geographic or rotated rasters, rasters placed by
        ground control points, RPCs or geolocation arrays (with the ``gdalwarp`` fix),
        an impossible or contradicting ``nodata``.
    """
    return with_unit(_load_file(path, spacing=spacing, vertical_scale=vertical_scale,
                                nodata=nodata, nodata_policy=nodata_policy,
                                fill_value=fill_value, key=key, channel=channel, band=band,
                                reproject=reproject, unit=unit, lines=lines), unit)


def with_unit(field, unit):
    """``field`` with the linear unit ``unit`` (None: unchanged); its heights stay in the
    pixel size's unit. Raises ValueError for an unknown unit or one that contradicts the
    field's CRS."""
    if unit is None:
        return field
    import dataclasses

    return dataclasses.replace(field, unit=unit, height_unit=None)


def _load_file(path, *, spacing=None, vertical_scale=1.0, nodata=None, nodata_policy="void",
               fill_value=None, key=None, channel=None, band=1, reproject=None,
               unit=None, lines=False) -> HeightField:
    """The body of :func:`load_file` (without the unit change)."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"path: {path} does not exist or is not a file")
    if nodata_policy not in NODATA_POLICIES:
        raise ValueError(f"nodata_policy: expected one of {NODATA_POLICIES}, got {nodata_policy!r}")
    if not (math.isfinite(vertical_scale) and vertical_scale != 0):
        raise ValueError(f"vertical_scale: must be a non-zero finite number, got {vertical_scale}")
    if spacing is not None:
        check_spacing(spacing)
    if unit is not None:
        unit_name(unit)  # an unknown unit raises before the file is read
    ext = os.path.splitext(path)[1].lower()
    if ext in RASTER_EXTENSIONS:
        field = read_raster(path, band=band, spacing=spacing, vertical_scale=vertical_scale,
                            nodata=nodata, reproject=reproject, lines=lines)
        if nodata_policy != "void" and field.nodata_mask is not None:
            heights, _ = _apply_nodata(field.heights, path, field.nodata_mask, nodata_policy,
                                       fill_value)
            field = HeightField(heights, field.name, spacing=None if field.transform is not None
                                else field.spacing, unit=field.unit, crs=field.crs,
                                transform=field.transform,
                                north=None if field.transform is not None else field.north,
                                nodata_mask=np.zeros(field.shape, dtype=bool),
                                params=dict(field.params, nodata_policy=nodata_policy))
        else:
            field.params["nodata_policy"] = nodata_policy
        return field
    mapped = _mapped(path, ext, spacing, vertical_scale, nodata, nodata_policy)
    if mapped is not None:
        return mapped
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
        elif ext in (".png", ".jpg", ".jpeg"):
            data = _read_image(path)
        elif ext == ".exr":
            data = _read_exr(path, channel)
        else:
            raise LoaderError(f"path: unknown extension {ext!r} of {path}; expected .npy, .npz, "
                             f"{', '.join(RASTER_EXTENSIONS)}, .png, .jpg, .jpeg or .exr")
    except LoaderError:
        raise
    except Exception as exc:  # a damaged file: say which one and what the reader said
        raise LoaderError(f"{path}: cannot be read as {ext} ({type(exc).__name__}: {exc})") from None
    data = np.asarray(data)
    if data.ndim != 2:
        raise ValueError(f"{path}: expected a 2D height array, got shape {data.shape}")
    line = None
    if lines and is_line(data.shape):
        data, _, line = thicken_line(data, np.zeros(data.shape, bool))
    if data.shape[0] < 2 or data.shape[1] < 2:
        raise too_small(path, data.shape)
    if data.dtype.kind not in "fiu":
        raise ValueError(f"{path}: heights must be real numbers, got dtype {data.dtype}")
    with np.errstate(over="ignore"):
        heights = data.astype(np.float64) * vertical_scale
        stored = heights.astype(np.float32)
    # the file's own non-finite samples are the voids; a finite one that the scale takes
    # beyond float32 (or float64) is refused below, as the window-by-window reader does
    mask = ~np.isfinite(data) if data.dtype.kind == "f" else np.zeros(data.shape, bool)
    if nodata is not None:
        check_nodata(nodata, data.dtype, None, path)
        mask |= data == nodata
    # a finite sample beyond float32 would become inf in the stored heights: refused here,
    # naming the file, as read_raster does
    _refuse(~np.isfinite(stored) & ~mask, str(path), (0, 0),
            lambda r, c: (f"{float(heights[r, c])!r}"
                          + (f" once scaled (in the file {data[r, c].item()!r})"
                             if vertical_scale != 1.0 else "")
                          + ", beyond float32 (heights are held in float32, |h| <= 3.4e38)"),
            "otherwise rescale the heights")
    del stored
    heights, mask = _apply_nodata(heights, path, mask, nodata_policy, fill_value)
    return HeightField(heights, os.path.basename(path), spacing=spacing,
                       nodata_mask=mask,
                       params=dict(path=path, spacing=spacing, vertical_scale=vertical_scale,
                                   nodata=nodata, nodata_policy=nodata_policy,
                                   **({} if line is None else {"line": line})))


def _mapped(path, ext, spacing, vertical_scale, nodata, policy):
    """A ``.npy``'s heights memory-mapped read-only, without a copy, where nothing needs
    converting: 2D C-ordered native float32, no nodata value, ``vertical_scale`` 1, and
    no non-finite sample unless the policy keeps voids. Else None: the general path
    reads and converts in memory."""
    if ext != ".npy" or vertical_scale != 1.0 or nodata is not None:
        return None
    try:
        data = np.load(path, mmap_mode="r", allow_pickle=False)
    except Exception:  # damaged: the general path says what is wrong
        return None
    if (data.ndim != 2 or data.dtype != np.dtype("=f4") or not data.flags.c_contiguous
            or min(data.shape) < 2):
        return None
    step = max(1, (1 << 20) // data.shape[1])
    voids = False
    for r0 in range(0, data.shape[0], step):  # bounded temporaries
        bad = ~np.isfinite(data[r0:r0 + step])
        if bad.any():
            if policy == "void":
                voids = True
                continue
            if policy != "error":
                return None  # filling needs a copy: the general path
            row, col = (int(v) for v in np.argwhere(bad)[0])
            raise ValueError(f"{path}: non-finite sample at (row {row + r0}, col {col}) = "
                             f"{data[row + r0, col]}; choose nodata_policy='void' (the "
                             "default), 'fill-min' or 'fill'")
    return HeightField(data, os.path.basename(path), spacing=spacing,
                       params=dict(path=path, spacing=spacing, vertical_scale=1.0, nodata=None,
                                   nodata_policy=policy, memory_mapped=True, voids=voids))


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

    Conversion: the spacing in degrees becomes metres on a sphere of the IUGG mean
    radius (:data:`algos.georef.IUGG_MEAN_EARTH_RADIUS_M`, 6,371,008.8 m), the east-west
    spacing scaled by cos(latitude) at the centre (about
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
    metres_per_degree = math.pi / 180 * IUGG_MEAN_EARTH_RADIUS_M
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
    # heights in cells (as the kernels' studies have always read them), rows running north
    return HeightField(heights, "jacksboro", spacing=cell, unit="m", height_unit="cell",
                       north="+y", crs=None,
                       params=dict(size=size, vertical_scale=vertical_scale, dx_m=dx_m,
                                   dy_m=dy_m, unit_metres=1.0,
                                   source="matplotlib sample data jacksboro_fault_dem.npz"))


def open_lazy(path, *, chunks=2048, spacing=None, vertical_scale=1.0, band=1,
              unit=None) -> HeightField:
    """:func:`_open_lazy` with ``unit`` as in :func:`load_file`."""
    return with_unit(_open_lazy(path, chunks=chunks, spacing=spacing,
                                vertical_scale=vertical_scale, band=band), unit)


def _open_lazy(path, *, chunks=2048, spacing=None, vertical_scale=1.0, band=1) -> HeightField:
    """A HeightField whose heights are a lazy dask array over the file (any raster GDAL
    reads, through rasterio windows, or a memory-mapped ``.npy``), read chunk by chunk
    where it is computed: for fields larger than memory (``algos.horizon`` and friends
    take it and work tile by tile). Heights are in the file's unit (scale, offset and
    ``vertical_scale`` applied), NaN at voids; a raster's CRS, transform and orientation
    are carried (a geographic or rotated raster, or one placed by GCPs, RPCs or
    geolocation arrays, is refused, as by ``load_file``)."""
    import dask.array as da

    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"path: {path} does not exist or is not a file")
    if not (math.isfinite(vertical_scale) and vertical_scale != 0):
        raise ValueError(f"vertical_scale: must be a non-zero finite number, got {vertical_scale}")
    raster = LazyRaster(path, scale=vertical_scale, band=band)
    if min(raster.shape) < 2:  # as load_file says it
        raise too_small(path, raster.shape)
    heights = da.from_array(raster, chunks=chunks, asarray=False, lock=False, fancy=False)
    params = dict(path=path, spacing=spacing, vertical_scale=vertical_scale, lazy=True,
                  chunks=chunks, band=band)
    name = os.path.basename(path)
    if os.path.splitext(path)[1].lower() == ".npy":
        return HeightField(heights, name, spacing=spacing, params=params)
    import rasterio

    from algos.georef import (
        check_axis_aligned,
        check_georeferencing,
        height_units_factor,
        heights_factor,
    )

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        ds = rasterio.open(path)
    with ds:
        check_georeferencing(ds, path)  # GCPs, RPCs, geolocation arrays: refused with the fix
        georef = ds.crs is not None or not ds.transform.is_identity
        if not georef:
            return HeightField(heights, name, spacing=spacing, params=params)
        if spacing is not None:
            raise ValueError(f"spacing: {path} is georeferenced; its geotransform gives the "
                             "spacing, so leave spacing out")
        check_axis_aligned(ds.transform, f"{path}: transform")
        # heights in another unit than the lengths (a compound CRS): converted on read
        mixed = heights_factor(ds.crs) if ds.crs is not None else None
        unit = check_crs(ds.crs, path, bounds=ds.bounds,
                         pixel=(ds.transform.a, ds.transform.e),
                         heights_converted=mixed is not None)
        band_units = ds.units[band - 1] if ds.units else None
        ratio = height_units_factor(band_units, unit) if mixed is None else None
        if ratio is not None:  # a band unit type ("ft") other than the CRS's unit
            mixed = (band_units, ratio)
        if mixed is not None:
            raster = LazyRaster(path, scale=vertical_scale * mixed[1], band=band)
            heights = da.from_array(raster, chunks=chunks, asarray=False, lock=False,
                                    fancy=False)
            params.update(heights_converted_from=mixed[0], heights_factor=mixed[1])
        params["unit_metres"] = float(ds.crs.linear_units_factor[1]) if ds.crs else 1.0
        params["nodata"] = ds.nodatavals[band - 1]
        return HeightField(heights, name, unit=unit, crs=ds.crs, transform=ds.transform,
                           params=params)


def undeclared_nodata(field, vertical_scale=1.0):
    """A common nodata value (:data:`COMMON_NODATA`) that ``field`` holds as heights, with
    no void declared at it: ``(value, count, (row, col))`` of its first sample (stored
    rows), or None. The value is compared times ``vertical_scale``, the factor the field
    was loaded with. Lazy (dask) fields are not read: None.

    Such a field is most likely a file whose voids are not declared (a GeoTIFF without a
    nodata tag, a ``.npy``): taken as heights, they sink the surface to -9999 and move
    every product and the default render camera. Declare them with
    ``load_file(path, nodata=value)`` (``--nodata`` on the command line)."""
    heights = field.heights
    if not isinstance(heights, np.ndarray) or heights.size == 0:
        return None
    low = float(np.nanmin(heights)) if np.isfinite(heights).any() else math.nan
    for value in COMMON_NODATA:
        if low == float(np.float32(value * vertical_scale)):
            hit = heights == low
            if field.nodata_mask is not None:
                hit &= ~field.nodata_mask
            count = int(np.count_nonzero(hit))
            if count:
                row, col = (int(v) for v in np.argwhere(hit)[0])
                return value, count, (row, col)
    return None
