"""The xarray paths of the products: a DataArray in, a DataArray out with the input's
coords, CRS and attributes, plus the product's parameters and how it was computed."""
from __future__ import annotations

import numpy as np

from ..field import HeightField
from .azimuths import _azimuth_list
from .curvature import _curvature_attrs
from .observers import VIEWSHED_UINT8_NODATA
from .stats import returned, with_stats


def _path_attrs(stats):
    """The attributes a product's DataArray or file records about how it was computed,
    from its :class:`~algos.terrain.stats.TerrainStats`: ``algorithm`` and ``paths`` (one
    per azimuth, comma-separated), and with snapping ``snapped_azimuths`` and
    ``snap_max_change_deg``."""
    attrs = dict(algorithm=stats.algorithm, paths=",".join(stats.paths))
    if stats.snapped_azimuths:
        attrs.update(_snap_attrs((stats.snapped_azimuths, stats.snap_max_change_deg)))
    return attrs


def _snap_attrs(snap):
    """The snapping ``snap`` = (azimuths used, largest change) as attributes."""
    return dict(snapped_azimuths=[float(a) for a in snap[0]], snap_max_change_deg=float(snap[1]))


def _with_path_attrs(out, stats, snap):
    """``out`` (a DataArray) with :func:`_path_attrs` of ``stats`` (the in-memory call's)
    and the snapping ``snap``; a lazy one (``stats`` None) records only the snapping (its
    algorithms are chosen when it is computed, tile by tile). Returns ``(out, stats)``."""
    if stats is None:
        if snap is not None:
            out.attrs.update(_snap_attrs(snap))
        return out, None
    out.attrs.update(_path_attrs(stats.with_snap(snap)))
    return out, stats


def _attr(value):
    """A parameter as a file/DataArray attribute (None as 'none')."""
    return "none" if value is None else value


def _to_dataarray(template, compute, product, attrs, extra_dim=None):
    """Run ``compute(HeightField)``, which returns ``(values, stats)``, on a DataArray's
    field and wrap the values like the input: same dims, coords, attrs and CRS
    (rioxarray), plus ``attrs`` (units and the product's parameters). A dask-backed input
    gives a dask-backed (lazy) output. Returns ``(DataArray, stats)``."""
    import xarray as xr

    field = HeightField.from_dataarray(template)
    values, stats = compute(field)
    dims, coords = template.dims, dict(template.coords)
    if extra_dim is not None:
        dims = (extra_dim[0],) + tuple(dims)
        coords[extra_dim[0]] = np.asarray(extra_dim[1], dtype=float)
    # the input's nodata value describes its heights, not the product: voids are NaN in a
    # float product, and a bool or count product has no fill value
    kept = {k: v for k, v in template.attrs.items() if k not in ("_FillValue", "nodata",
                                                                 "missing_value")}
    out = xr.DataArray(values, dims=dims, coords=coords, name=product,
                       attrs={**kept, "product": product, **{k: v for k, v in attrs.items()}})
    crs = getattr(getattr(template, "rio", None), "crs", None) if hasattr(template, "rio") else None
    if crs is not None:
        out = out.rio.write_crs(crs)
        out = out.rio.write_nodata(np.nan if np.dtype(out.dtype).kind == "f" else None,
                                   encoded=False)
    if product == "viewshed" and out.dtype == np.uint8:
        # the output values' viewshed stores its voids as 255: the file's nodata
        if hasattr(out, "rio"):
            out = out.rio.write_nodata(VIEWSHED_UINT8_NODATA, encoded=False)
        else:
            out.attrs["_FillValue"] = VIEWSHED_UINT8_NODATA
    return out, stats


def _azimuth_product_dataarray(product, name, heights, azimuths, max_distance, snap,
                               return_stats, attrs, **options):
    """The DataArray path of a product over many azimuths (:func:`sky_view_factor`,
    :func:`openness`): ``product(field, azimuths=..., max_distance=..., **options)`` on
    the DataArray's field, wrapped as ``name`` with ``attrs`` first, then ``n_azimuths``,
    ``max_distance``, the curvature parameters (``options["curvature"]``,
    ``options["refraction"]``), the paths and the snapping ``snap``. Returns what the
    product returns: the DataArray, or ``(DataArray, TerrainStats)`` with
    ``return_stats``."""
    az = _azimuth_list(azimuths)
    out, stats = _to_dataarray(heights, lambda f: with_stats(
        product, f, azimuths=az, max_distance=max_distance, **options), name,
        dict(**attrs, n_azimuths=len(az), max_distance=_attr(max_distance),
             **_curvature_attrs(options["curvature"], options["refraction"])))
    return returned(*_with_path_attrs(out, stats, snap), return_stats)
