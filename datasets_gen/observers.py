"""Observers where the user means them: map coordinates on a georeferenced field, or
pixel columns and rows counted the same way on every input.

* Map coordinates ``X,Y`` (in the field's CRS) go through
  :meth:`algos.HeightField.map_to_grid`: the vertex is the pixel centre.
* Pixel coordinates ``COL,ROW`` count columns from the western edge and rows from the
  northern edge (row 0 at the top of the north-up picture), whatever the storage order:
  a south-up raster or the embedded DEM (rows running north) is counted the same way.

Both return grid coordinates of the stored array, what :func:`algos.viewshed` takes.
Errors echo what was typed.
"""
from __future__ import annotations

import csv
import math
import os

__all__ = ["parse_observer", "read_observers_csv", "pixel_to_grid"]


def pixel_to_grid(field, col, row, *, what=None):
    """Grid ``(col, row)`` of the stored array from a pixel counted from the north-west
    corner (north-up rows); raises ValueError echoing ``what`` outside the footprint."""
    typed = what if what is not None else f"{col},{row}"
    # a line (load_file(lines=True)) is held twice; its pixels are the file's own
    rows, cols = field.params.get("line", {}).get("shape", field.shape)
    if not (0 <= col <= cols - 1 and 0 <= row <= rows - 1):
        raise ValueError(f"observer pixel {typed}: outside {field.name}, whose columns are "
                         f"0..{cols - 1} and rows 0..{rows - 1} (row 0 north)")
    return float(col), float(field.north_up_row(row))


def parse_observer(text, field, *, pixel=False):
    """``(col, row, height)`` from ``"X,Y"`` or ``"X,Y,HEIGHT"``: map coordinates, or with
    ``pixel`` a pixel counted from the north-west corner. ``height`` is None when not
    given (the caller's default applies); in the field's unit otherwise.

    Raises
    ------
    ValueError
        Naming what was typed: not two or three numbers, not finite, outside the field,
        map coordinates on a field without georeferencing.
    """
    parts = [p.strip() for p in str(text).split(",")]
    flag = "--observer-pixel" if pixel else "--observer"
    if len(parts) not in (2, 3):
        raise ValueError(f"{flag} {text!r}: expected {'COL,ROW' if pixel else 'X,Y'} or "
                         f"{'COL,ROW' if pixel else 'X,Y'},HEIGHT (two or three numbers)")
    try:
        values = [float(p) for p in parts]
    except ValueError:
        raise ValueError(f"{flag} {text!r}: expected numbers") from None
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"{flag} {text!r}: expected finite numbers")
    height = values[2] if len(values) == 3 else None
    if height is not None and height < 0:
        raise ValueError(f"{flag} {text!r}: the height above the ground must be >= 0")
    if pixel:
        col, row = pixel_to_grid(field, values[0], values[1], what=text)
    else:
        if field.transform is None:
            raise ValueError(f"{flag} {text!r}: {field.name} is not georeferenced, so map "
                             "coordinates mean nothing; give a pixel with --observer-pixel "
                             "COL,ROW")
        col, row = field.map_to_grid(values[0], values[1], what=text)
    return col, row, height


def read_observers_csv(path, field, *, pixel=False):
    """Observers from a CSV file of ``x,y[,height]`` lines (a header line of words is
    skipped): a list of :func:`parse_observer` results. Errors name the file and line."""
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise ValueError(f"observers: {path} does not exist or is not a file")
    out = []
    with open(path, newline="", encoding="utf-8-sig") as f:  # a BOM (spreadsheets) is no text
        for number, line in enumerate(csv.reader(f), start=1):
            if not line or all(not c.strip() for c in line):
                continue
            if number == 1 and all(any(ch.isalpha() for ch in c) for c in line if c.strip()):
                continue  # a header: words only
            try:
                out.append(parse_observer(",".join(line), field, pixel=pixel))
            except ValueError as exc:
                raise ValueError(f"{path}, line {number}: {exc}") from None
    if not out:
        raise ValueError(f"observers: {path} holds no observer")
    return out


def _numeric(text):
    try:
        float(text)
    except ValueError:
        return False
    return True
