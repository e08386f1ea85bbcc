"""Heights from a DataArray's stored values: the packing and void conventions it carries.

An ``xarray.DataArray`` may hold raw stored values together with the rules that turn
them into physical ones, in two places:

* ``attrs``: the rules have *not* been applied. rioxarray's ``open_rasterio(path)``
  (its default ``mask_and_scale=False``) keeps a GeoTIFF's raw counts with the band's
  ``scale_factor``/``add_offset`` and its nodata as ``_FillValue``; a netCDF variable
  opened with ``decode_cf=False`` or ``mask_and_scale=False`` keeps the CF attributes
  ``scale_factor``, ``add_offset``, ``_FillValue``, ``missing_value``, ``valid_min``,
  ``valid_max`` and ``valid_range`` (CF Conventions 1.11, sections 2.5.1 and 8.1).
  The per-band lists of GDAL (``scales``, ``offsets``, ``nodatavals``, as xarray's
  former ``open_rasterio`` wrote them) are the same rules for a one-band array.
* ``encoding``: xarray's decoder has applied them already (values scaled, voids NaN);
  they are kept only to write the file back, and must not be applied twice.

:func:`decode` applies the first and leaves the second, and refuses a rule it cannot
apply (a zero or non-finite scale, a non-numeric fill) or the same rule in both places,
naming the attribute.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["decode", "PACKING_ATTRS", "VOID_ATTRS", "BAND_LISTS"]

#: Attributes that scale raw values: ``physical = raw * scale_factor + add_offset``.
PACKING_ATTRS = ("scale_factor", "add_offset")
#: Attributes that mark raw values as voids (compared before scaling, as CF says).
VOID_ATTRS = ("_FillValue", "missing_value", "nodata", "valid_min", "valid_max",
              "valid_range")
#: GDAL's per-band lists (xarray's former ``open_rasterio``) -> the single-value name.
BAND_LISTS = {"scales": "scale_factor", "offsets": "add_offset", "nodatavals": "nodata"}


def _numbers(value, name, what):
    """The finite or NaN floats of an attribute (a scalar or a sequence)."""
    values = np.atleast_1d(np.asarray(value))
    if values.dtype.kind not in "fiub" or values.ndim != 1:
        raise ValueError(f"{what}: attribute {name}={value!r} is not a number, so the "
                         "stored values cannot be decoded; fix or drop the attribute")
    return [float(v) for v in values]


def _scale(attrs, name, default, what):
    if name not in attrs:
        return default
    values = _numbers(attrs[name], name, what)
    if len(values) != 1 or not math.isfinite(values[0]) or (name == "scale_factor"
                                                            and values[0] == 0):
        raise ValueError(f"{what}: attribute {name}={attrs[name]!r} cannot scale heights "
                         "(expected one finite number, non-zero for scale_factor)")
    return values[0]


def decode(array, data, what, extra_fills=None):
    """``(data, mask)``: the heights of ``array`` in physical units with NaN at voids, and
    the bool void mask (None when there is none), from its stored ``data`` (numpy or
    dask, possibly ``array.data`` itself).

    Rules found in ``array.attrs`` are applied: values equal to ``_FillValue``,
    ``missing_value`` or ``nodata``, or outside ``valid_min``/``valid_max``/
    ``valid_range``, are voids (raw values compared), then ``raw * scale_factor +
    add_offset`` (as float64); the per-band lists ``scales``, ``offsets`` and
    ``nodatavals`` of one band count as those. ``extra_fills`` are more raw void values
    (rioxarray's ``rio.nodata`` where no attribute holds it). Rules found in
    ``array.encoding`` are already applied by xarray's decoder and are left alone.

    Raises
    ------
    ValueError
        Naming ``what`` and the attribute: a rule given in both ``attrs`` and
        ``encoding`` (applied already, or not?), a non-numeric value, a zero or
        non-finite ``scale_factor``, a per-band list of more than one value, or a list
        that disagrees with its single-value name.
    """
    attrs = dict(array.attrs)
    encoding = dict(getattr(array, "encoding", {}) or {})
    for name in PACKING_ATTRS + VOID_ATTRS:
        if name in attrs and name in encoding and name != "_FillValue":
            raise ValueError(f"{what}: {name} is both an attribute ({attrs[name]!r}: not "
                             f"applied yet) and an encoding ({encoding[name]!r}: applied by "
                             "the decoder); keep one")
    # GDAL's per-band lists (xarray's former open_rasterio: scales, offsets, nodatavals):
    # one band here, so one value each, the same rule as the CF names
    for plural, single in BAND_LISTS.items():
        if plural in attrs:
            values = _numbers(attrs[plural], plural, what)
            if len(values) != 1:
                raise ValueError(f"{what}: attribute {plural}={attrs[plural]!r} holds one "
                                 f"value per band, but the array is one band; select the "
                                 "band's value or drop the attribute")
            if single in attrs and _numbers(attrs[single], single, what) != values:
                raise ValueError(f"{what}: attributes {plural}={attrs[plural]!r} and "
                                 f"{single}={attrs[single]!r} disagree; keep one")
            attrs.setdefault(single, values[0])
    scale = _scale(attrs, "scale_factor", 1.0, what)
    offset = _scale(attrs, "add_offset", 0.0, what)
    fills = [float(v) for v in extra_fills or ()]
    for name in ("_FillValue", "missing_value", "nodata"):
        if attrs.get(name) is not None:
            fills += _numbers(attrs[name], name, what)
    low = high = None
    if "valid_range" in attrs:
        bounds = _numbers(attrs["valid_range"], "valid_range", what)
        if len(bounds) != 2:
            raise ValueError(f"{what}: attribute valid_range={attrs['valid_range']!r} is not "
                             "a pair (min, max)")
        low, high = bounds
    if "valid_min" in attrs:
        low = _numbers(attrs["valid_min"], "valid_min", what)[0]
    if "valid_max" in attrs:
        high = _numbers(attrs["valid_max"], "valid_max", what)[0]

    mask = None
    for value in fills:
        if math.isnan(value):
            continue  # a NaN fill: NaN samples are voids anyway
        hit = data == value
        mask = hit if mask is None else mask | hit
    for bound, outside in ((low, lambda v: data < v), (high, lambda v: data > v)):
        if bound is not None:
            hit = outside(bound)
            mask = hit if mask is None else mask | hit
    if scale != 1.0 or offset != 0.0:
        data = data.astype(np.float64) * scale + offset
    if mask is not None:
        if type(data).__module__.split(".")[0] == "dask":
            import dask.array as da

            data = da.where(mask, np.nan, data)
        else:
            data = np.where(mask, np.nan, data)
    return data, mask
