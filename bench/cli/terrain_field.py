"""The one field loader of the terrain commands (``hftrace horizon|shadows|svf|openness|
viewshed``, ``--dask`` too, and ``hftrace render``'s ``--fill``): a file through
``datasets_gen.load_file`` or ``open_lazy``, or a generated or embedded dataset."""
from __future__ import annotations

import os

import numpy as np

import algos

__all__ = ["load_terrain", "fill_policy"]

#: Options that describe a file, meaningless for a generated dataset
_FILE_OPTIONS = (("band", 1), ("spacing", None), ("unit", None), ("reproject", None), ("fill", None),
                 ("vertical_scale", 1.0), ("nodata", None))


def fill_policy(text):
    """(nodata_policy, fill_value) of ``--fill``: None keeps the voids."""
    if text is None:
        return "void", None
    if text == "min":
        return "fill-min", None
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"--fill: expected 'min' or a height, got {text!r}") from None
    return "fill", value


def note_undeclared_nodata(field, source, vertical_scale=1.0):
    """A note on stderr when ``field`` (loaded from ``source``) holds a common nodata
    value as its lowest height and declares no void there
    (:func:`datasets_gen.loaders.undeclared_nodata`): the heights are used as they are,
    and the note says how to declare them (``--nodata``)."""
    import sys

    from datasets_gen.loaders import undeclared_nodata

    found = undeclared_nodata(field, vertical_scale)
    if found is not None:
        value, count, (row, col) = found
        print(f"hftrace: note: {source} declares no nodata, but {count} sample"
              f"{'s' * (count != 1)} equal {value:g} (the first at row {row}, col {col}), a "
              f"common nodata value; they are taken as heights. If they are voids, give "
              f"--nodata {value:g}", file=sys.stderr)
    return found


def _is_file_name(source):
    """Whether ``source`` names a file rather than a dataset (a path or an extension)."""
    return os.sep in source or (os.altsep is not None and os.altsep in source) \
        or os.path.splitext(source)[1] != ""


def load_terrain(args, lazy_chunks=None):
    """The HeightField of ``args.source``: a file (any raster GDAL reads, ``.npy``, PNG,
    EXR) or a dataset name. With ``lazy_chunks``, a lazy (dask) field read window by
    window. Raises ValueError naming the source or the option."""
    import datasets_gen

    source = args.source
    if os.path.exists(source) or _is_file_name(source):
        if not os.path.isfile(source):
            raise ValueError(f"source: {source} does not exist or is not a file")
        policy, fill_value = fill_policy(args.fill)
        if lazy_chunks is not None:
            for option in ("reproject", "fill", "nodata"):
                if getattr(args, option) is not None:
                    raise ValueError(f"--{option}: not available with --dask (prepare the file "
                                     "first, e.g. with gdalwarp, and give it as it is)")
            field = datasets_gen.open_lazy(source, chunks=lazy_chunks, band=args.band,
                                           spacing=args.spacing, unit=args.unit,
                                           vertical_scale=args.vertical_scale)
        else:
            # a one-row or one-column file is a line, which the viewshed takes (as
            # algos.viewshed does a one-row array)
            field = datasets_gen.load_file(source, band=args.band, spacing=args.spacing,
                                           unit=args.unit,
                                           vertical_scale=args.vertical_scale,
                                           reproject=args.reproject, nodata_policy=policy,
                                           fill_value=fill_value, nodata=args.nodata,
                                           lines=args.command == "viewshed")
            note_undeclared_nodata(field, source, args.vertical_scale)
        if field.unit == "cell":  # in memory and with --dask alike
            import sys

            print(f"hftrace: note: {source} has no georeferencing and no --spacing: its "
                  "heights are taken in multiples of the pixel size (cell units)",
                  file=sys.stderr)
        return field
    for option, default in (("size", None), ("seed", 1), ("param", None)):
        if getattr(args, option) != default and os.path.isfile(source):
            raise ValueError(f"--{option}: describes a generated dataset, not the file {source}")
    known = [row["name"] for row in datasets_gen.catalogue()]
    if source not in known:
        raise ValueError(f"source: {source!r} is neither a file nor a dataset; datasets are "
                         f"{', '.join(known)}")
    for option, default in _FILE_OPTIONS:
        if getattr(args, option) != default:
            raise ValueError(f"--{option.replace('_', '-')}: describes a file; {source} is a "
                             "generated or embedded dataset")
    field = datasets_gen.load(source, size=args.size, seed=args.seed, **dict(args.param or []))
    if lazy_chunks is not None:
        import dask.array as da

        field = algos.HeightField(
            da.from_array(np.asarray(field.heights), chunks=lazy_chunks), field.name,
            spacing=field.spacing, unit=field.unit, height_unit=field.height_unit,
            crs=field.crs, transform=field.transform, north=field.north, params=field.params)
    return field
