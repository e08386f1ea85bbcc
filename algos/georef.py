"""Where a grid lies on the Earth: Earth radii, pixel sizes from a geotransform, map
coordinates <-> grid coordinates.

Grid coordinates are those of docs/CONVENTIONS.md: vertex ``(i, j)`` is the sample
``H[j, i]`` (column i, row j of the array as stored). A georeferenced raster's affine
geotransform maps *pixel-corner* coordinates ``(col, row)`` to map ``(x, y)``; its
samples sit at pixel centres, so vertex ``(i, j)`` is at map
``transform * (i + 0.5, j + 0.5)`` (GDAL's "pixel is area" convention, the GeoTIFF
default).

Earth radii (one constant per meaning):

* :data:`WGS84_SEMI_MAJOR_AXIS_M`, 6 378 137 m: the equatorial radius of the WGS 84
  ellipsoid (NIMA TR8350.2, 2000). GDAL's viewshed uses the semi-major axis of the
  raster's ellipsoid for curvature (``gdal_viewshed``, "-cc"), so the terrain products'
  curvature default uses it too, for agreement with that peer.
* :data:`IUGG_MEAN_EARTH_RADIUS_M`, 6 371 008.8 m: the IUGG mean radius R1 = (2a + b) / 3
  (Moritz, "Geodetic Reference System 1980", Bulletin Geodesique 54, 1980). It is used
  where degrees of latitude and longitude become metres on a sphere: the embedded
  Jacksboro DEM's conversion to square cells.
"""
from __future__ import annotations

import math
import os
import re

import numpy as np

__all__ = ["WGS84_SEMI_MAJOR_AXIS_M", "IUGG_MEAN_EARTH_RADIUS_M", "pixel_size", "utm_epsg",
           "check_axis_aligned", "LINEAR_UNITS", "UNIT_ALIASES", "NO_UNIT", "unit_name",
           "unit_metres", "crs_unit", "check_crs", "vertical_unit", "heights_factor",
           "check_height_units", "height_units_factor", "ground_size",
           "unusable_georeferencing", "check_georeferencing",
           "check_dataarray_georeferencing", "check_nodata"]

#: Equatorial radius of the WGS 84 ellipsoid (m): the curvature default (as GDAL's viewshed).
WGS84_SEMI_MAJOR_AXIS_M = 6378137.0
#: IUGG mean Earth radius R1 (m): degrees to metres on a sphere (the embedded DEM).
IUGG_MEAN_EARTH_RADIUS_M = 6371008.8

#: The linear units a field accepts by name, with their exact length in metres: the metre,
#: the kilometre, the international foot (0.3048 m exactly, 1959) and the US survey foot
#: (1200/3937 m exactly, the unit of many US State Plane CRSs such as EPSG:2277). A CRS
#: brings its own unit and factor (rasterio's ``CRS.linear_units_factor``), whatever it is.
LINEAR_UNITS = {"m": 1.0, "km": 1000.0, "ft": 0.3048, "US survey foot": 1200.0 / 3937.0}
#: Other spellings of those units (PROJ's and rasterio's names among them) -> the name used.
UNIT_ALIASES = {"metre": "m", "meter": "m", "kilometre": "km", "kilometer": "km",
                "foot": "ft", "international foot": "ft", "us-ft": "US survey foot",
                "ftUS": "US survey foot", "US survey foot": "US survey foot"}
#: The names of a field without a real unit: ``"cell"`` (cell units, spacing 1) and
#: ``"map unit"`` (a pixel size whose unit nobody gave). Curvature refuses both.
NO_UNIT = ("cell", "map unit")


#: Spellings of a linear unit in a DataArray's CF ``units`` attribute (lower case) -> name
_HEIGHT_UNIT_SPELLINGS = {"m": "m", "metre": "m", "metres": "m", "meter": "m", "meters": "m",
                          "km": "km", "kilometre": "km", "kilometres": "km",
                          "kilometer": "km", "kilometers": "km", "ft": "ft", "foot": "ft",
                          "feet": "ft", "international foot": "ft", "us-ft": "US survey foot",
                          "ftus": "US survey foot", "us survey foot": "US survey foot",
                          "us survey feet": "US survey foot"}


def height_units_factor(units, unit):
    """The factor that converts heights in ``units`` (a CF ``units`` attribute, a GDAL
    band's unit type) into the linear unit ``unit``; None when ``units`` names no linear
    unit, ``unit`` is no real unit, or the two agree (within 10 ppm: "ft" on a US survey
    foot grid differs by 2 ppm, below any DEM's error)."""
    name = _HEIGHT_UNIT_SPELLINGS.get(units.strip().lower()) if isinstance(units, str) else None
    if name is None or unit not in LINEAR_UNITS or name == unit:
        return None
    ratio = LINEAR_UNITS[name] / LINEAR_UNITS[unit]
    return None if abs(ratio - 1.0) < 1e-5 else ratio


def check_height_units(units, unit, what) -> None:
    """Raise ValueError when a DataArray's CF ``units`` attribute names a linear unit other
    than ``unit``, the field's (its CRS's) linear unit: heights in feet over a metre grid
    would give every slope wrong by the ratio. An attribute that names no linear unit
    (absent, "metres above sea level", "radians") is not read."""
    ratio = height_units_factor(units, unit)
    if ratio is None:
        return
    raise ValueError(f"{what}: its heights are in {units!r} (attrs['units']) but its "
                     f"lengths in {unit} (its CRS); read as they are, every slope would be "
                     f"off by a factor {ratio:.10g}. Convert them first: "
                     f"(array * {ratio:.10g}).assign_attrs(units={unit!r})")


def unit_name(unit) -> str:
    """The name a field uses for ``unit``: one of :data:`LINEAR_UNITS` (aliases of
    :data:`UNIT_ALIASES` mapped to it) or of :data:`NO_UNIT`. Raises ValueError naming
    ``unit`` and the accepted names for anything else (an angle such as "degree" is not a
    linear unit)."""
    if not isinstance(unit, str):
        raise TypeError(f"unit: expected a unit name, got {unit!r}")
    name = UNIT_ALIASES.get(unit, unit)
    if name in LINEAR_UNITS or name in NO_UNIT:
        return name
    raise ValueError(f"unit: {unit!r} is not a linear unit hftrace knows; accepted: "
                     f"{', '.join(repr(u) for u in LINEAR_UNITS)} (also "
                     f"{', '.join(repr(a) for a in UNIT_ALIASES if a not in LINEAR_UNITS)}), "
                     f"or {' / '.join(repr(u) for u in NO_UNIT)} for no real unit; a "
                     "geographic unit (degrees) must be reprojected first (gdalwarp)")


def unit_metres(unit):
    """Metres per ``unit`` (a name :func:`unit_name` accepts), or None for the names of
    :data:`NO_UNIT`."""
    return LINEAR_UNITS.get(unit_name(unit))


def check_axis_aligned(transform, name: str = "transform") -> None:
    """Raise ValueError when an affine geotransform is rotated or sheared (its b or d
    term is not zero), or when its columns run west (a negative x pixel size): the grid's
    rows and columns must run along the map axes, columns eastward."""
    b, d = float(transform.b), float(transform.d)
    if b != 0.0 or d != 0.0:
        raise ValueError(
            f"{name}: the geotransform is rotated or sheared (row/column terms b = {b:g}, "
            f"d = {d:g}); hftrace needs rows and columns along the map axes. Resample it "
            "first, e.g. `gdalwarp -r bilinear IN.tif OUT.tif` (which writes a north-up grid)")
    if float(transform.a) == 0.0 or float(transform.e) == 0.0:
        raise ValueError(f"{name}: the geotransform has a zero pixel size "
                         f"({transform.a:g} x {transform.e:g})")
    # columns must run east: azimuths are measured from the grid's axes, and only the
    # rows' direction (north-up or south-up) is recorded, so a west-running x axis
    # would mirror every azimuth east-west
    if float(transform.a) < 0.0:
        raise ValueError(
            f"{name}: the geotransform's x pixel size is negative ({transform.a:g}): its "
            "columns run west, and hftrace needs them running east. Resample it first, "
            "e.g. `gdalwarp -r near IN.tif OUT.tif` (which writes a north-up grid); for a "
            "DataArray, array.sortby('x')")


def pixel_size(transform) -> tuple[float, float, bool]:
    """``(dx, dy, north_up)`` of an axis-aligned geotransform: the pixel sizes as positive
    lengths in the CRS's unit, and whether row 0 is the northern edge (a negative y
    pixel size, the usual north-up raster) rather than the southern one (south-up)."""
    check_axis_aligned(transform)
    return abs(float(transform.a)), abs(float(transform.e)), float(transform.e) < 0


def utm_epsg(longitude: float, latitude: float) -> int:
    """The EPSG code of the WGS 84 UTM zone that holds a point: 326zz north of the
    equator, 327zz south (zz = 1 + floor((lon + 180) / 6), the plain zone rule, without
    the Norway and Svalbard exceptions)."""
    if not (math.isfinite(longitude) and math.isfinite(latitude) and -90 <= latitude <= 90):
        raise ValueError(f"longitude, latitude: ({longitude}, {latitude}) is not a position")
    zone = int(math.floor((((longitude + 180.0) % 360.0)) / 6.0)) + 1
    zone = min(max(zone, 1), 60)
    return (32600 if latitude >= 0 else 32700) + zone


def ground_size(pixel, latitude):
    """East-west and north-south ground lengths (m) of a pixel of ``pixel`` = (dlon,
    dlat) degrees at ``latitude``, on the IUGG mean sphere."""
    metres_per_degree = math.pi / 180.0 * IUGG_MEAN_EARTH_RADIUS_M
    return (abs(pixel[0]) * metres_per_degree * math.cos(math.radians(latitude)),
            abs(pixel[1]) * metres_per_degree)


def _gdalwarp_fix(path, pixel, bounds) -> str:
    """The command that reprojects a geographic raster to the UTM zone of its centre."""
    lon = (bounds.left + bounds.right) / 2
    lat = (bounds.bottom + bounds.top) / 2
    epsg = utm_epsg(lon, lat)
    dx, dy = ground_size(pixel, lat)
    stem, _ = os.path.splitext(os.fspath(path))
    return (f"gdalwarp -t_srs EPSG:{epsg} -tr {dx:.6g} {dy:.6g} -r bilinear {path} "
            f"{stem}_utm.tif "
            f"(or read it with reproject='utm'; the CLI option is --reproject utm)")


def vertical_unit(crs):
    """``(name, metres per unit)`` of the vertical part of a compound CRS (its ``VERT_CS``
    unit, as GDAL writes it in WKT 1), or None when the CRS has no vertical part."""
    from rasterio.crs import CRS

    wkt = CRS.from_user_input(crs).to_wkt()
    start = wkt.find("VERT_CS[")
    if start < 0:
        return None
    found = re.search(r'UNIT\["([^"]+)",\s*([0-9.eE+-]+)', wkt[start:])
    return (UNIT_ALIASES.get(found.group(1), found.group(1)), float(found.group(2))) \
        if found else None


def heights_factor(crs):
    """``(vertical unit name, factor)`` that converts the heights of a compound CRS whose
    vertical unit differs from its linear unit into the linear unit (0.3048006096 for US
    survey feet over a metre grid); None when the units agree or there is no vertical
    part."""
    vertical = vertical_unit(crs)
    if vertical is None:
        return None
    from rasterio.crs import CRS

    _, metres = CRS.from_user_input(crs).linear_units_factor
    ratio = vertical[1] / float(metres)
    return None if abs(ratio - 1.0) <= 1e-12 else (vertical[0], ratio)


def crs_unit(crs, what, *, bounds=None, pixel=(1.0, 1.0), source=None,
             heights_converted=False):
    """``(name, metres)`` of a CRS's linear unit: the name a field uses
    (:func:`unit_name` for the units it knows, else PROJ's own name) and
    metres per unit, both from rasterio (``CRS.linear_units_factor``). A geographic CRS
    raises ValueError naming ``what`` and, with ``bounds`` and ``pixel`` (the pixel size in
    degrees), the exact ``gdalwarp`` command that fixes ``source`` (default ``what``)."""
    from rasterio.crs import CRS

    crs = CRS.from_user_input(crs)
    if crs.is_geographic:
        fix = _gdalwarp_fix(what if source is None else source, pixel, bounds) \
            if bounds is not None else "gdalwarp -t_srs EPSG:<UTM zone> IN.tif OUT.tif"
        raise ValueError(f"{what}: its CRS ({crs.to_string()}) is geographic: pixel sizes in "
                         f"degrees are not lengths, and heights in metres over degrees give "
                         f"wrong angles. Reproject it first: {fix}")
    name, factor = crs.linear_units_factor
    name = UNIT_ALIASES.get(name, name)
    # a compound CRS may put heights in another unit than lengths (UTM metres with
    # NAVD88 heights in US survey feet): slopes would be off by the ratio
    mixed = None if heights_converted else heights_factor(crs)
    if mixed is not None:
        vname, ratio = mixed
        epsg = crs.to_epsg()
        label = f"EPSG:{epsg}" if epsg else re.match(r'\w+\["([^"]*)"', crs.to_wkt()).group(1)
        raise ValueError(f"{what}: its CRS ({label}) gives "
                         f"heights in {vname} but lengths in {name}; read as they are, every "
                         f"slope would be off by a factor {ratio:.10g}. Convert the heights "
                         f"to {name} first (multiply by {ratio:.10g}) and drop the vertical "
                         "CRS, or read the file with datasets_gen.load_file, which converts "
                         "them")
    return name, float(factor)


def check_crs(crs, what, *, bounds=None, pixel=(1.0, 1.0), heights_converted=False) -> str:
    """The linear unit name of a CRS (None: no CRS, returns "map unit"). A geographic CRS
    raises ValueError naming ``what`` and, with ``bounds`` and ``pixel`` (the pixel size
    in degrees), the exact ``gdalwarp`` command that fixes the file; so does a compound
    CRS whose heights are in another unit, unless ``heights_converted``."""
    if crs is None:
        return "map unit"
    return crs_unit(crs, what, bounds=bounds, pixel=pixel,
                    heights_converted=heights_converted)[0]


def _target_epsg(crs, longitude, latitude):
    """The EPSG code to warp to: a projected CRS's own, else the WGS 84 UTM zone of the
    point (longitude, latitude in degrees), else None when neither is known."""
    if crs is not None and not crs.is_geographic and crs.to_epsg() is not None:
        return crs.to_epsg()
    if longitude is not None and latitude is not None:
        return utm_epsg(longitude, latitude)
    return None


def unusable_georeferencing(ds):
    """``(kind, gdalwarp command)`` when a rasterio dataset is georeferenced only by ground
    control points (``"ground control points"``), rational polynomial coefficients
    (``"RPCs"``) or geolocation arrays (``"geolocation arrays"``), which place pixels on the
    map without an axis-aligned geotransform; None when it has a geotransform or no
    georeferencing at all. The command orthorectifies (``-rpc``) or warps (``-geoloc``, or
    the GCPs' polynomial) the file to a projected north-up grid, the UTM zone of its
    centre when its own CRS is geographic (``<EPSG>`` when that centre is unknown)."""
    if ds.crs is not None or not ds.transform.is_identity:
        return None
    path = ds.name
    stem, _ = os.path.splitext(os.fspath(path))
    out = f"{stem}_warped.tif"
    gcps, gcp_crs = ds.gcps
    if gcps:
        xs = [p.x for p in gcps]
        ys = [p.y for p in gcps]
        centre = ((min(xs) + max(xs)) / 2, (min(ys) + max(ys)) / 2)
        geographic = gcp_crs is None or gcp_crs.is_geographic
        epsg = _target_epsg(gcp_crs, *(centre if geographic and gcp_crs is not None
                                       else (None, None)))
        return ("ground control points",
                f"gdalwarp -t_srs EPSG:{epsg or '<EPSG>'} -r bilinear {path} {out}")
    if ds.rpcs is not None:
        epsg = _target_epsg(None, ds.rpcs.long_off, ds.rpcs.lat_off)
        return ("RPCs", f"gdalwarp -rpc -t_srs EPSG:{epsg} -r bilinear {path} {out} "
                        "(add -to RPC_DEM=<dem.tif> for terrain-corrected orthorectification)")
    if "GEOLOCATION" in ds.tag_namespaces():
        return ("geolocation arrays",
                f"gdalwarp -geoloc -t_srs EPSG:<UTM zone of the area> -r bilinear {path} {out}")
    return None


def check_georeferencing(ds, what) -> None:
    """Raise ValueError naming ``what`` when a rasterio dataset is georeferenced only by
    ground control points, RPCs or geolocation arrays (:func:`unusable_georeferencing`):
    read as a plain grid it would lose where its pixels lie and how large they are."""
    found = unusable_georeferencing(ds)
    if found is not None:
        kind, fix = found
        raise ValueError(f"{what}: is georeferenced by {kind}, not by an axis-aligned "
                         "geotransform, so its pixel size and position are unknown to "
                         f"hftrace; orthorectify or warp it to a projected grid first: {fix}")


def check_dataarray_georeferencing(array, what) -> None:
    """Raise ValueError naming ``what`` when a DataArray without a usable geotransform
    came from a raster georeferenced only by ground control points, RPCs or geolocation
    arrays: rioxarray keeps the GCPs in its grid-mapping coordinate (``gcps``), and the
    file it was read from (``encoding["source"]``) tells the rest."""
    grid_mapping = (getattr(array, "encoding", {}) or {}).get("grid_mapping", "spatial_ref")
    if grid_mapping in array.coords and "gcps" in array.coords[grid_mapping].attrs:
        crs = array.coords[grid_mapping].attrs.get("crs_wkt")
        epsg = None
        if crs:
            from rasterio.crs import CRS

            crs = CRS.from_user_input(crs)
            epsg = None if crs.is_geographic else crs.to_epsg()
        raise ValueError(f"{what}: is georeferenced by ground control points "
                         f"({grid_mapping}.attrs['gcps']), not by an axis-aligned "
                         "geotransform, so its pixel size and position are unknown to "
                         "hftrace; warp the file it came from to a projected grid first: "
                         f"gdalwarp -t_srs EPSG:{epsg or '<EPSG>'} -r bilinear IN.tif OUT.tif")
    source = (getattr(array, "encoding", {}) or {}).get("source")
    if isinstance(source, str) and os.path.isfile(source):
        import warnings

        import rasterio

        with warnings.catch_warnings():
            warnings.simplefilter("ignore", rasterio.errors.NotGeoreferencedWarning)
            try:
                ds = rasterio.open(source)
            except rasterio.errors.RasterioIOError:
                return  # not a raster GDAL reads (a netCDF through another engine, ...)
        with ds:
            check_georeferencing(ds, f"{what} (read from {source})")


def check_nodata(nodata, dtype, file_nodata, what) -> None:
    """Raise ValueError naming ``what`` with both values when an explicit ``nodata`` can
    never mark a void of a file: no sample of ``dtype`` can equal it (-9999 or 2.5 in
    uint8, NaN in an integer type, 1e40 in float32), or the file declares another nodata
    value (``file_nodata``; None: it declares none). A NaN nodata equals a NaN one."""
    if isinstance(nodata, (bool, np.bool_)) or not isinstance(nodata, (int, float, np.number)):
        raise TypeError(f"nodata: expected a number, got {nodata!r}")
    value = float(nodata)
    dtype = np.dtype(dtype)
    if dtype.kind in "iu":
        info = np.iinfo(dtype)
        if not (math.isfinite(value) and value == math.floor(value)
                and info.min <= value <= info.max):
            raise ValueError(f"nodata: {nodata!r} can never equal a sample of {what}, whose "
                             f"type {dtype.name} holds integers in [{info.min}, {info.max}]; "
                             "give a value of that type (or leave nodata out to use the "
                             "file's own)")
    elif dtype.kind == "f" and math.isfinite(value) and float(dtype.type(value)) != value:
        raise ValueError(f"nodata: {nodata!r} can never equal a sample of {what}, whose type "
                         f"{dtype.name} cannot hold it exactly (nearest "
                         f"{float(dtype.type(value))!r})")
    if file_nodata is not None:
        same = (math.isnan(value) and math.isnan(file_nodata)) or value == file_nodata
        if not same:
            raise ValueError(f"nodata: {nodata!r} contradicts the nodata value {file_nodata!r} "
                             f"that {what} declares; leave nodata out to use the file's, or "
                             "correct the file first (gdal_edit.py -a_nodata VALUE FILE)")
