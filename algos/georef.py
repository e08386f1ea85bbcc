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

__all__ = ["WGS84_SEMI_MAJOR_AXIS_M", "IUGG_MEAN_EARTH_RADIUS_M", "pixel_size", "utm_epsg",
           "check_axis_aligned", "LINEAR_UNITS", "UNIT_ALIASES", "NO_UNIT", "unit_name",
           "unit_metres"]

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
    term is not zero): the grid's rows and columns must run along the map axes."""
    b, d = float(transform.b), float(transform.d)
    if b != 0.0 or d != 0.0:
        raise ValueError(
            f"{name}: the geotransform is rotated or sheared (row/column terms b = {b:g}, "
            f"d = {d:g}); hftrace needs rows and columns along the map axes. Resample it "
            "first, e.g. `gdalwarp -r bilinear IN.tif OUT.tif` (which writes a north-up grid)")
    if float(transform.a) == 0.0 or float(transform.e) == 0.0:
        raise ValueError(f"{name}: the geotransform has a zero pixel size "
                         f"({transform.a:g} x {transform.e:g})")


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
