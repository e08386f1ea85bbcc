"""Rasters through rasterio (GDAL): read any DEM GDAL reads, write georeferenced products.

Reading (:func:`read_raster`)
-----------------------------
Anything GDAL opens: GeoTIFF with any compression or predictor (LZW, DEFLATE, ZSTD,
predictor 2 or 3), tiled or striped, BigTIFF, VRT, and the other GDAL formats. One band
(``band``, 1-based) is read; its scale and offset are applied (``heights = raw * scale
+ offset``); the nodata mask (the band's nodata value, an internal mask, NaN) marks the
voids, which become NaN in the heights and True in ``nodata_mask``.

Units and orientation. The pixel size comes from the geotransform, in the CRS's linear
unit (``unit``, with ``params["unit_metres"]`` metres per unit); heights are taken to be
in that same unit (times ``vertical_scale``, e.g. 0.3048 for feet over a metre grid).
Rows are kept as stored: a south-up raster (positive y pixel size) is read in its true
orientation (``north="+y"``) and the products return their results on the same grid.
Rotated or sheared geotransforms are refused, and so is a file georeferenced only by
ground control points, RPCs or geolocation arrays, with the ``gdalwarp`` command that
warps it to a projected grid (:func:`algos.georef.check_georeferencing`). A geographic CRS (degrees) is refused
with the exact ``gdalwarp`` command that fixes the file, or reprojected on request
(``reproject="utm"``: to the WGS 84 UTM zone of the centre, bilinear, at the ground size
of the pixel at the centre, through ``rasterio.warp``; see :func:`_to_utm`). A file without georeferencing
gets ``spacing`` (default 1: cell units).

Writing (:func:`write_product`, :func:`create_product`, :func:`write_window`)
------------------------------------------------------------------------------
Products are written as tiled (256 x 256), DEFLATE-compressed GeoTIFF (predictor 3 for
floats, 2 for integers) on the input's grid: its CRS, geotransform and orientation.
Void vertices are nodata: NaN for float products, 255 for bool products (stored as
uint8 0/1) and 65535 for uint16 counts; the GeoTIFF's nodata is set accordingly. The
tags record the product, its units and its parameters. :func:`create_product` makes an
empty file of that layout, :func:`write_window` writes one window of it: the Dask path.
Writes of one file must not overlap in time (GDAL rewrites whole compressed tiles):
pass a lock shared by the writers (``distributed.Lock``) when they run in parallel.

The memory-mapped fast path of earlier versions is gone for GeoTIFF: GDAL decodes
blocks into memory and cannot map a file's pixels in place. ``.npy`` keeps it
(:func:`datasets_gen.load_file`).
"""
from __future__ import annotations

import math
import os
import warnings

import numpy as np

from algos.field import HeightField
from algos.georef import (
    check_axis_aligned,
    check_crs,
    check_georeferencing,
    check_nodata,
    crs_unit,
    ground_size,
    height_units_factor,
    heights_factor,
    utm_epsg,
    vertical_unit,
)

__all__ = ["read_raster", "check_crs", "crs_unit", "write_product", "create_product", "write_window",
           "product_nodata", "save_product", "LazyRaster", "REPROJECT", "thicken_line", "is_line",
           "too_small"]

#: What ``reproject=`` accepts: None (refuse a geographic CRS) or "utm".
REPROJECT = (None, "utm")
#: Nodata of integer products: bool products are written as uint8 (0/1, voids 255),
#: counts as uint16 (voids 65535).
BOOL_NODATA = 255
COUNT_NODATA = 65535


def _check_band(ds, band, path):
    if isinstance(band, bool) or not isinstance(band, (int, np.integer)):
        raise TypeError(f"band: expected a band number (1-based int), got {band!r}")
    if not 1 <= band <= ds.count:
        raise ValueError(f"band: {band} is not a band of {path}, which has {ds.count} "
                         f"band{'s' if ds.count != 1 else ''} (1..{ds.count})")
    return int(band)


def _georeferenced(ds) -> bool:
    return ds.crs is not None or not ds.transform.is_identity


def _refuse(bad, where, origin, what, otherwise):
    """``ValueError`` naming ``where``, the first sample of the boolean array ``bad`` (its row
    and column offset by ``origin``), ``what(r, c)`` says of it, and how many there are."""
    if bad.any():
        r, c = (int(v) for v in np.argwhere(bad)[0])
        raise ValueError(f"{where}: the sample at row {r + origin[0]}, column {c + origin[1]} "
                         f"is {what(r, c)}; {int(bad.sum())} sample(s) in all. If it marks "
                         f"voids, declare it as the nodata value; {otherwise}")


def _scaled(raw, mask, scale, offset, vertical_scale, where="the raster", origin=(0, 0)):
    """Heights as float32: raw * scale + offset, times vertical_scale, voids NaN.

    A sample that is not a void (``mask``) raises ``ValueError`` naming ``where``, its row
    and column (offset by ``origin``, a window's corner) and its value when it is
    infinite in the file, or finite in the file but infinite once scaled and held in
    float32 (|h| > 3.4e38, or beyond float64 by the scale): it would otherwise become a
    void without a word. NaN samples are voids."""
    raw = np.asarray(raw)
    if scale == 1.0 and offset == 0.0 and vertical_scale == 1.0 and raw.dtype == np.float32:
        heights = np.array(raw, dtype=np.float32)
        wide = heights
    else:
        with np.errstate(over="ignore", invalid="ignore"):
            wide = (raw.astype(np.float64) * scale + offset) * vertical_scale
            heights = wide.astype(np.float32)
    if raw.dtype.kind == "f":
        _refuse(np.isinf(raw) & ~mask, where, origin,
                lambda r, c: f"{float(raw[r, c])!r}, an infinite height",
                "otherwise mend the file")
    _refuse(np.isfinite(raw) & ~np.isfinite(heights) & ~mask, where, origin,
            lambda r, c: (f"{float(wide[r, c])!r}"
                          + ("" if float(wide[r, c]) == float(raw[r, c]) else
                             f" once scaled (in the file {raw[r, c].item()!r})")
                          + ", beyond float32 (heights are held in float32, |h| <= 3.4e38)"),
            "otherwise rescale the heights")
    mask = mask | ~np.isfinite(heights)
    heights[mask] = np.nan
    return heights, mask


def thicken_line(raw, mask, *, before=False):
    """A one-row or one-column raster (``raw`` and its void ``mask``) as a field: the line
    repeated to two rows (columns), ``before`` (a one-row raster stored south-up) with the
    copy first so that the line is the northern row. Returns ``(raw, mask, line)``, where
    ``line`` says where the file's own samples are: ``{"shape": (rows, cols), "rows": (r0,
    r1), "cols": (c0, c1)}``. Along the line the surface of the doubled field is the
    polyline through its samples, as :func:`algos.viewshed` reads a one-row array."""
    rows, cols = raw.shape
    axis = 0 if rows == 1 else 1
    order = (1, 0) if before else (0, 1)
    raw2 = np.concatenate([raw, raw], axis=axis)
    mask2 = np.concatenate([mask, mask], axis=axis)
    start = order[0]
    line = {"shape": (rows, cols),
            "rows": (start, start + 1) if axis == 0 else (0, rows),
            "cols": (0, cols) if axis == 0 else (0, 1)}
    return raw2, mask2, line


def is_line(shape):
    """Whether ``shape`` is a one-row or one-column raster of at least two samples."""
    return len(shape) == 2 and min(shape) == 1 and max(shape) >= 2


def too_small(path, shape):
    """The ValueError of a file with fewer than 2 x 2 samples (every reader's, in memory
    and window by window); a line is told where it is taken."""
    text = f"{path}: a height field needs at least 2 x 2 samples, got {tuple(shape)}"
    if is_line(shape):
        text += ("; a one-row or one-column file is a line, which only the viewshed takes, "
                 "in memory (load_file(lines=True); hftrace viewshed without --dask)")
    return ValueError(text)


def read_raster(path, *, band=1, spacing=None, vertical_scale=1.0, nodata=None,
                reproject=None, lines=False) -> HeightField:
    """A HeightField from any raster GDAL reads (see the module docstring).

    Parameters
    ----------
    path : str or path-like
    band : int
        1-based band number.
    spacing : float or (dx, dy), optional
        Pixel size of a file *without* georeferencing (default 1: cell units). Refused for
        a georeferenced file, whose geotransform says it.
    vertical_scale : float
        A factor on the heights after scale/offset (a unit change of the heights).
    nodata : float, optional
        The nodata value of a file that declares none (its internal mask, if any, is
        kept); it must be a value of the file's type, and equal the file's own if it has
        one (:func:`algos.georef.check_nodata`).
    reproject : None or "utm"
        What to do with a geographic CRS: refuse (None) or reproject to the UTM zone of
        the centre.
    lines : bool
        Accept a one-row or one-column raster (a line, which only the viewshed takes):
        the field holds it twice (:func:`thicken_line`) and ``params["line"]`` says where
        its own samples are. Default False: such a raster raises.

    Returns
    -------
    HeightField
        float32 heights in the CRS's linear unit (NaN at voids), ``transform``, ``crs``,
        ``nodata_mask``, ``north`` and ``params`` (path, band, scale, offset, nodata,
        unit_metres).

    Raises
    ------
    ValueError
        A missing file, a band out of range, a rotated transform, georeferencing by
        GCPs, RPCs or geolocation arrays, a geographic CRS without ``reproject``, a
        ``nodata`` no sample can equal or that contradicts the file's, a bad
        ``spacing``/``vertical_scale``; each names the file or argument.
    """
    import rasterio

    path = os.fspath(path)
    if reproject not in REPROJECT:
        raise ValueError(f"reproject: expected None or 'utm', got {reproject!r}")
    if not (math.isfinite(vertical_scale) and vertical_scale != 0):
        raise ValueError(f"vertical_scale: must be a non-zero finite number, got {vertical_scale}")
    with warnings.catch_warnings():  # a file without georeferencing is handled below
        warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
        try:
            ds = rasterio.open(path)
        except rasterio.errors.RasterioIOError as exc:
            raise ValueError(f"{path}: cannot be read as a raster ({exc})") from None
    with ds:
        band = _check_band(ds, band, path)
        check_georeferencing(ds, path)  # GCPs, RPCs, geolocation arrays: refused with the fix
        georef = _georeferenced(ds)
        if georef and spacing is not None:
            raise ValueError(f"spacing: {path} is georeferenced (pixel size "
                             f"{abs(ds.transform.a):g} x {abs(ds.transform.e):g}); its "
                             "geotransform gives the spacing, so leave spacing out")
        transform = ds.transform
        if georef:
            check_axis_aligned(transform, f"{path}: transform")
        if georef and ds.crs is None:
            # a pixel size without a unit: 30 (metres?) and 1/3600 (degrees?) look alike
            raise ValueError(f"{path}: has a geotransform (pixel size {abs(transform.a):g} x "
                             f"{abs(transform.e):g}) but no CRS, so the unit of its lengths "
                             "is unknown; assign its CRS first, e.g. gdal_edit.py -a_srs "
                             f"EPSG:32633 {path} (with the file's real EPSG code)")
        scale = float(ds.scales[band - 1] if ds.scales else 1.0)
        offset = float(ds.offsets[band - 1] if ds.offsets else 0.0)
        file_nodata = ds.nodatavals[band - 1]
        raw = ds.read(band)
        mask = ds.read_masks(band) == 0
        if nodata is not None:
            check_nodata(nodata, raw.dtype, file_nodata, f"{path} (band {band})")
            if file_nodata is None:  # the file's own mask (internal mask, NaN) stays
                mask |= (raw == nodata) if not math.isnan(nodata) else np.isnan(raw)
        crs = ds.crs
        geographic = crs is not None and crs.is_geographic
        if geographic:
            if reproject is None:
                check_crs(crs, path, bounds=ds.bounds, pixel=(ds.transform.a, ds.transform.e))
            # the file's own samples are checked before the resampling blends them into
            # their neighbours, so a refusal quotes the file's sample, row and column
            vertical = vertical_unit(ds.crs)
            _scaled(raw, mask, scale, offset, vertical_scale * (vertical[1] if vertical else 1.0),
                    where=str(path))
            raw, mask, transform, crs = _to_utm(ds, raw, mask, band)
        # heights in another unit than the lengths (a compound CRS): converted here; a
        # geographic one was reprojected onto a metre grid
        mixed = None
        if georef and ds.crs is not None:
            mixed = heights_factor(ds.crs) if not geographic else vertical_unit(ds.crs)
            if geographic and mixed is not None:
                mixed = None if mixed[1] == 1.0 else mixed
        unit = check_crs(crs, path, heights_converted=mixed is not None) if georef else \
            ("cell" if spacing is None else "map unit")
        # a band whose unit type (GDAL's, e.g. "ft") differs from the CRS's linear unit
        band_units = ds.units[band - 1] if ds.units else None
        ratio = height_units_factor(band_units, unit) if mixed is None else None
        if ratio is not None:
            mixed = (band_units, ratio)
    line = None
    if lines and is_line(raw.shape):
        # a one-row raster stored south-up keeps its line the northern row, its place on
        # the map unchanged (the copy one pixel south of it)
        south_up = georef and raw.shape[0] == 1 and transform.e > 0
        raw, mask, line = thicken_line(raw, mask, before=south_up)
        if south_up:
            from affine import Affine

            transform = transform @ Affine.translation(0, -1)
    if min(raw.shape) < 2:
        raise too_small(path, raw.shape)
    heights, mask = _scaled(raw, mask, scale, offset,
                            vertical_scale * (mixed[1] if mixed else 1.0), where=str(path))
    params = dict(path=path, band=band, scale=scale, offset=offset,
                  nodata=nodata if nodata is not None else file_nodata,
                  vertical_scale=vertical_scale,
                  reprojected=reproject if geographic else None)
    if mixed:
        params.update(heights_converted_from=mixed[0], heights_factor=mixed[1])
    if line is not None:
        params["line"] = line
    if georef:
        return HeightField(heights, os.path.basename(path), unit=unit, crs=crs,
                           transform=transform, nodata_mask=mask, params=params)
    return HeightField(heights, os.path.basename(path), spacing=spacing, unit=unit,
                       nodata_mask=mask, params=params)


def _to_utm(ds, raw, mask, band):
    """``(raw, mask, transform, crs)`` reprojected from a geographic CRS to the UTM zone
    of the centre (rasterio.warp, bilinear; voids stay voids), with pixels of the ground
    size of the centre pixel: east-west and north-south lengths of its sides on the
    IUGG mean sphere, so rectangular in general (3" at 46 N: 64.4 m x 92.7 m)."""
    from rasterio.crs import CRS
    from rasterio.warp import Resampling, calculate_default_transform, reproject

    lon = (ds.bounds.left + ds.bounds.right) / 2
    lat = (ds.bounds.bottom + ds.bounds.top) / 2
    dst_crs = CRS.from_epsg(utm_epsg(lon, lat))
    ground = ground_size((ds.transform.a, ds.transform.e), lat)
    transform, width, height = calculate_default_transform(
        ds.crs, dst_crs, ds.width, ds.height, *ds.bounds, resolution=ground)
    data = raw.astype(np.float64)
    data[mask] = np.nan
    out = np.full((height, width), np.nan)
    reproject(data, out, src_transform=ds.transform, src_crs=ds.crs, src_nodata=np.nan,
              dst_transform=transform, dst_crs=dst_crs, dst_nodata=np.nan,
              resampling=Resampling.bilinear)
    return out, ~np.isfinite(out), transform, dst_crs


# ---- writing ------------------------------------------------------------------------------

def product_nodata(dtype):
    """``(file dtype, nodata)`` of a product array's dtype: float -> (float32, NaN), bool
    and uint8 (a viewshed's output values) -> (uint8, 255), other integers -> (uint16,
    65535)."""
    dtype = np.dtype(dtype)
    if dtype.kind == "b" or dtype == np.uint8:
        return np.dtype(np.uint8), BOOL_NODATA
    if dtype.kind in "iu":
        return np.dtype(np.uint16), COUNT_NODATA
    return np.dtype(np.float32), float("nan")


def _grid_of(field):
    """``(transform, crs, flip)`` of the output grid of ``field``: its own, or for a field
    without georeferencing a north-up grid of its pixel size whose vertex (0, 0) (north-up)
    is the map point (0, 0) (the array is flipped when the field's rows run north)."""
    from affine import Affine

    if field.transform is not None:
        return field.transform, field.crs, False
    dx, dy = field.dx, field.dy
    return Affine(dx, 0.0, -dx / 2, 0.0, -dy, dy / 2), field.crs, not field.north_up


def _window_shape(field, window):
    """``(rows, cols)`` of ``field``'s grid cut to ``window`` (row and column slices of
    the stored array; None: all of it)."""
    if window is None:
        return field.shape
    return tuple(len(range(*s.indices(n))) for s, n in zip(window, field.shape))


def _profile(field, count, dtype, nodata, blocksize=256, compress="deflate", window=None):
    transform, crs, flip = _grid_of(field)
    rows, cols = _window_shape(field, window)
    if window is not None:
        from affine import Affine

        if flip:
            raise ValueError("window: a field without georeferencing stored south-up is "
                             "written flipped; cut it after to_north_up")
        (r0, _, _), (c0, _, _) = (s.indices(n) for s, n in zip(window, field.shape))
        transform = transform @ Affine.translation(c0, r0)  # the window's first pixel
    tiled = rows >= 16 and cols >= 16
    profile = dict(driver="GTiff", height=rows, width=cols, count=count, dtype=dtype.name,
                   crs=crs, transform=transform, nodata=nodata, compress=compress,
                   predictor=3 if dtype.kind == "f" else 2, BIGTIFF="IF_SAFER")
    if tiled:
        block = min(blocksize, 16 * max(1, min(rows, cols) // 16))
        profile.update(tiled=True, blockxsize=block, blockysize=block)
    return profile


def _tags(product, units, params):
    tags = {"product": product, "units": units}
    for key, value in (params or {}).items():
        tags[str(key)] = "none" if value is None else str(value)
    return tags


def write_product(path, array, field, *, product, units, params=None, band_names=None,
                  compress="deflate", window=None) -> str:
    """Write a terrain product as a tiled, compressed GeoTIFF on ``field``'s grid.

    Parameters
    ----------
    path : str or path-like
    array : (rows, cols) or (K, rows, cols) array
        The product in the field's stored orientation (as the products return it): float
        (NaN at voids), bool, or an integer count.
    field : HeightField
        The input: its CRS, transform, orientation and ``nodata_mask`` go into the file.
    product : str
        Its name ("horizon", "shadows", "sky_view_factor", "viewshed", ...).
    units : str
        The unit of the values ("degrees", "radians", "1", ...), recorded as a tag.
    params : dict, optional
        The product's parameters, recorded as tags (``azimuth``, ``max_distance``, ...).
    band_names : sequence of str, optional
        One description per band (e.g. "azimuth 90").
    window : (slice, slice), optional
        The rows and columns of ``field``'s stored grid that ``array`` covers (a line's
        own samples, ``params["line"]``); the file is that window of the grid, with its
        geotransform. Default: the whole grid.

    Returns
    -------
    str
        The path written. Voids are nodata (see :func:`product_nodata`).
    """
    import rasterio

    path = os.fspath(path)
    values = np.asarray(array)
    if values.ndim == 2:
        values = values[None]
    shape = _window_shape(field, window)
    if values.ndim != 3 or values.shape[1:] != shape:
        raise ValueError(f"array: expected shape {shape} or (K, *{shape}), got "
                         f"{np.shape(array)}")
    dtype, nodata = product_nodata(values.dtype)
    data = values.astype(dtype)
    if field.nodata_mask is not None:
        voids = np.asarray(field.nodata_mask)
        data[:, voids if window is None else voids[window]] = nodata
    profile = _profile(field, len(data), dtype, nodata, compress=compress, window=window)
    _, _, flip = _grid_of(field)
    if flip:
        data = field.to_north_up(data)
    with rasterio.open(path, "w", **profile) as dst:
        dst.write(data)
        dst.update_tags(**_tags(product, units, params))
        for k in range(len(data)):
            dst.update_tags(k + 1, units=units)
            if band_names is not None:
                dst.set_band_description(k + 1, str(band_names[k]))
    return path


def create_product(path, field, *, dtype, product, units, params=None, count=1,
                   compress="deflate") -> str:
    """An empty (all nodata) product GeoTIFF on ``field``'s grid, laid out as
    :func:`write_product` writes, for :func:`write_window` to fill: the Dask path, where
    each worker writes its finished tiles."""
    import rasterio

    path = os.fspath(path)
    file_dtype, nodata = product_nodata(dtype)
    profile = _profile(field, count, file_dtype, nodata, compress=compress)
    with rasterio.open(path, "w", **profile) as dst:
        dst.update_tags(**_tags(product, units, params))
        for k in range(count):
            dst.update_tags(k + 1, units=units)
    return path


def write_window(path, array, row_off, col_off, *, band=1, mask=None, lock=None) -> None:
    """Write ``array`` (rows, cols) into the GeoTIFF at ``path`` (made by
    :func:`create_product` or :func:`write_product`) at window (``row_off``,
    ``col_off``) of the file's grid, converted to the file's dtype, with the file's
    nodata where ``array`` is NaN or ``mask`` (a bool window, True at voids) is set.
    ``lock`` (a context manager) is held around the write: writes of one file must not
    overlap in time."""
    import contextlib

    import rasterio
    from rasterio.windows import Window

    values = np.asarray(array)
    with (lock if lock is not None else contextlib.nullcontext()):
        with rasterio.open(path, "r+") as dst:
            rows, cols = values.shape
            if not (0 <= row_off and 0 <= col_off and row_off + rows <= dst.height
                    and col_off + cols <= dst.width):
                raise ValueError(f"window: rows {row_off}..{row_off + rows}, cols "
                                 f"{col_off}..{col_off + cols} outside {path} "
                                 f"({dst.height} x {dst.width})")
            dtype = np.dtype(dst.dtypes[band - 1])
            data = values.astype(dtype) if values.dtype.kind != "f" or dtype.kind == "f" else \
                np.where(np.isnan(values), dst.nodata, values).astype(dtype)
            if mask is not None:
                data[np.asarray(mask, dtype=bool)] = dst.nodata
            dst.write(data, band, window=Window(col_off, row_off, cols, rows))


# ---- windows: the lazy reader -------------------------------------------------------------------

class LazyRaster:
    """One band of a raster read window by window through rasterio: what
    ``dask.array.from_array`` wraps so that each task reads only its own chunk. Pickles as
    its path and options (workers open the file themselves). Heights come out as float32
    in the file's unit (scale, offset and ``vertical_scale`` applied), NaN at voids; a
    ``.npy`` file is memory-mapped instead, its NaN and infinite samples voids (as
    ``load_file``'s default ``nodata_policy="void"``)."""

    def __init__(self, path, scale=1.0, band=1):
        self.path = os.fspath(path)
        self.scale = float(scale)
        self.band = band
        self.ndim = 2
        self.dtype = np.dtype(np.float32)
        if self._is_npy():
            probe = np.load(self.path, mmap_mode="r", allow_pickle=False)
            if probe.ndim != 2:
                raise ValueError(f"{self.path}: expected a 2D height array, got shape {probe.shape}")
            if probe.dtype.kind not in "fiu":
                raise ValueError(f"{self.path}: heights must be real numbers, got dtype {probe.dtype}")
            self.shape = tuple(probe.shape)
            return
        import rasterio

        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
                ds = rasterio.open(self.path)
            with ds:
                self.band = _check_band(ds, band, self.path)
                self.shape = (ds.height, ds.width)
        except rasterio.errors.RasterioIOError as exc:
            raise ValueError(f"{self.path}: cannot be read as a raster ({exc})") from None

    def _is_npy(self):
        return os.path.splitext(self.path)[1].lower() == ".npy"

    def __getitem__(self, key):
        if self._is_npy():
            window = np.asarray(np.load(self.path, mmap_mode="r", allow_pickle=False)[key])
            corner = tuple(k.indices(n)[0] if isinstance(k, slice) else int(k)
                           for k, n in zip(key, self.shape))
            # a .npy declares no nodata: its NaN and infinite samples are the voids, as
            # load_file's default nodata_policy "void" reads them in memory
            voids = ~np.isfinite(window) if window.dtype.kind == "f" else \
                np.zeros(window.shape, bool)
            heights, _ = _scaled(window, voids, 1.0, 0.0, self.scale, where=self.path,
                                 origin=corner)
            return heights
        import rasterio
        from rasterio.windows import Window

        rows, cols = (slice(*k.indices(n)[:2]) if isinstance(k, slice) else k
                      for k, n in zip(key, self.shape))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            ds = rasterio.open(self.path)
        with ds:
            w = Window(cols.start, rows.start, cols.stop - cols.start, rows.stop - rows.start)
            raw = ds.read(self.band, window=w)
            mask = ds.read_masks(self.band, window=w) == 0
            scale = float(ds.scales[self.band - 1] if ds.scales else 1.0)
            offset = float(ds.offsets[self.band - 1] if ds.offsets else 0.0)
        heights, _ = _scaled(raw, mask, scale, offset, self.scale, where=str(self.path),
                             origin=(rows.start, cols.start))
        return heights

    def __getstate__(self):
        return {"path": self.path, "scale": self.scale, "band": self.band, "shape": self.shape}

    def __setstate__(self, state):
        self.path, self.scale, self.shape = state["path"], state["scale"], state["shape"]
        self.band = state.get("band", 1)
        self.ndim, self.dtype = 2, np.dtype(np.float32)


def save_product(prefix, array, field, *, product, units, params=None, band_names=None,
                 observers=None, cmap="viridis", border=None, window=None) -> list[str]:
    """What a command writes for one product: ``prefix.tif`` (:func:`write_product`, of
    ``window`` of the field's grid when given) and ``prefix.png``
    (:func:`datasets_gen.preview.product_png`, the first band for a multi-band array; a
    window is drawn as stored, ``observers`` in its coordinates). Returns the two paths."""
    from .preview import product_png

    tif = write_product(f"{prefix}.tif", array, field, product=product, units=units,
                        params=params, band_names=band_names, window=window)
    first = np.asarray(array)
    first = first[0] if first.ndim == 3 else first
    shown = dict(params or {})
    if band_names is not None and np.asarray(array).ndim == 3:
        shown["band"] = band_names[0]
    png = product_png(f"{prefix}.png", first, field if window is None else None,
                      product=product, units=units,
                      params=shown, observers=observers, cmap=cmap, border=border)
    return [tif, png]
