"""The options of the terrain commands (``hftrace horizon|shadows|svf|openness|viewshed``,
in memory and with ``--dask``): their argparse types, the checks between them, the output
prefix, the observers and the parameters recorded in the files' tags."""
from __future__ import annotations

import argparse
import math
import os

import algos
from algos.georef import LINEAR_UNITS, UNIT_ALIASES

__all__ = ["PRODUCTS", "UNIT_CHOICES", "spacing_arg", "viewshed_values", "check_options",
           "output_prefix", "observers", "observers_tag", "azimuths_option", "product_options"]

#: The products: command -> help text
PRODUCTS = (("horizon", "horizon angles (degrees) along azimuths"),
            ("shadows", "cast shadows for a sun azimuth and elevation"),
            ("svf", "sky-view factor (Zaksek et al. 2011)"),
            ("openness", "positive or negative openness (Yokoyama et al. 2002), degrees"),
            ("viewshed", "what one or more observers see"))

#: What --unit accepts: the linear units of algos.georef (aliases included)
UNIT_CHOICES = tuple(LINEAR_UNITS) + tuple(a for a in UNIT_ALIASES if a not in LINEAR_UNITS)


def spacing_arg(text):
    """``D`` or ``DX,DY``: a pixel size (positive lengths), as argparse type."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected D or DX,DY (lengths), got {text!r}") from None
    if len(values) not in (1, 2) or not all(math.isfinite(v) and v > 0 for v in values):
        raise argparse.ArgumentTypeError(f"expected D or DX,DY (positive lengths), got {text!r}")
    return values[0] if len(values) == 1 else values


def viewshed_values(args):
    """The viewshed's output values given on the command line, by API keyword."""
    return {name: getattr(args, name) for name in ("visible_value", "invisible_value",
                                                    "out_of_range_value")
            if getattr(args, name) is not None}


def check_options(args):
    """Options that contradict each other are refused; defaults that depend on others are
    filled in (``--n-azimuths`` 16 unless ``--azimuths`` names them; the observer height
    1.75 unless ``--mode observer`` computes it)."""
    if args.command == "viewshed":
        values = viewshed_values(args)
        if args.observer_height is not None and not math.isfinite(args.observer_height):
            raise ValueError(f"--observer-height: the observer height is not finite, got "
                             f"{args.observer_height!r}")
        if args.mode == "observer":
            if args.observer_height is not None:
                raise ValueError("--observer-height: --mode observer computes the observer "
                                 "height; leave it out")
        elif args.observer_height is None:
            args.observer_height = algos.terrain.DEFAULT_OBSERVER_HEIGHT
        if args.mode != "normal":
            for name in ("visible_value", "invisible_value"):
                if name in values:
                    raise ValueError(f"--{name.replace('_', '-')}: applies to --mode normal "
                                     f"only (--mode {args.mode} gives a number per vertex)")
        if args.dask and (args.mode != "normal" or values):
            raise ValueError(f"--mode: --dask gives visibility only (--mode normal without "
                             f"output values), got --mode {args.mode}"
                             f"{' with output values' if values else ''}")
    if not getattr(args, "curvature", False) and \
            getattr(args, "refraction", algos.DEFAULT_REFRACTION) != algos.DEFAULT_REFRACTION:
        raise ValueError(f"--refraction: applies with --curvature only (got --refraction "
                         f"{args.refraction:g} without it)")
    if args.command in ("svf", "openness"):
        if args.azimuths is not None and args.n_azimuths is not None:
            raise ValueError("--n-azimuths: --azimuths already names the azimuths; give one "
                             "of the two")
        if args.azimuths is not None and getattr(args, "rational", False):
            # --rational moves the equally spaced azimuths only: with --azimuths it did
            # nothing, and the exact sweep the user asked for did not run
            raise ValueError("--rational: moves the equally spaced azimuths of --n-azimuths; "
                             "with --azimuths give --snap-denominator 5 (the same snapping)")
        if args.n_azimuths is None and args.azimuths is None:
            args.n_azimuths = 16


def output_prefix(args):
    """``--out`` as a path prefix: a trailing product extension (``.tif``, ``.png``,
    ``.exr``) is dropped, and a folder (an existing one, or a path ending in a separator)
    gets the command's name inside it. Raises ValueError when an output would overwrite
    the input file."""
    out = args.out
    if out.endswith(os.sep) or os.path.isdir(out):
        out = os.path.join(out, args.command)
    stem, ext = os.path.splitext(out)
    if ext.lower() in (".tif", ".tiff", ".png", ".exr"):
        out = stem
    source = os.path.abspath(args.source) if os.path.exists(args.source) else None
    for ext in (".tif", ".png", ".exr"):
        if source is not None and os.path.abspath(out + ext) == source:
            raise ValueError(f"--out: {out + ext} is the input file; choose another name")
    return out


def observers(args, field):
    """``[(col, row, height or None)]`` in grid coordinates of the stored array, from
    ``--observer`` (map coordinates), ``--observer-pixel`` and ``--observers`` (a CSV);
    default one observer at the centre."""
    from datasets_gen.observers import parse_observer, read_observers_csv

    out = [parse_observer(text, field) for text in args.observer]
    out += [parse_observer(text, field, pixel=True) for text in args.observer_pixel]
    if args.observers:
        out += read_observers_csv(args.observers, field, pixel=args.observers_pixel)
    if not out:
        raise ValueError("--observer: give at least one observer (--observer X,Y in map "
                         "coordinates, --observer-pixel COL,ROW, or --observers FILE.csv)")
    return out


def observers_tag(obs, field):
    """The ``observers`` tag of a viewshed's files: ``[[col, row(, height)]]`` of
    :func:`observers` (grid coordinates of ``field``'s stored array) as pixels counted
    from the north-west corner, as ``--observer-pixel`` takes them whatever the file's
    orientation (a line's own samples are its northern row), with the height when one
    was given. A tag can therefore be given back as ``--observer-pixel COL,ROW[,HEIGHT]``."""
    return [[round(c, 6), round(float(field.north_up_row(r)), 6)] + ([h] if h is not None else [])
            for c, r, h in obs]


def azimuths_option(args):
    """``--azimuths`` as a list of degrees, or None when not given."""
    if args.azimuths is None:
        return None
    try:
        return [float(v) for v in args.azimuths.split(",")]
    except ValueError:
        raise ValueError(f"--azimuths: expected comma-separated degrees, got "
                         f"{args.azimuths!r}") from None


def product_options(args, field):
    """The product's parameters as the user gave them (recorded in the files' tags)."""
    kind = args.command
    options = dict(max_distance=args.max_distance, algorithm=args.algorithm or "auto",
                   unit=field.unit)
    if kind == "horizon":
        options["azimuths"] = azimuths_option(args) or [0.0]
    elif kind == "svf":
        az = azimuths_option(args)
        options.update(azimuths=az) if az else options.update(n_azimuths=args.n_azimuths,
                                                               rational=args.rational)
    elif kind == "openness":
        az = azimuths_option(args)
        options.update(kind=args.kind)
        options.update(azimuths=az) if az else options.update(n_azimuths=args.n_azimuths,
                                                               rational=args.rational)
    elif kind == "shadows":
        options.update(azimuth=args.azimuth, elevation=args.elevation)
    else:
        options.update(observer_height=args.observer_height, target_height=args.target_height,
                       curvature=args.curvature, refraction=args.refraction,
                       mode=getattr(args, "mode", "normal"), **viewshed_values(args))
    if kind != "viewshed":
        options.update(curvature=args.curvature)
        if args.curvature:
            options.update(refraction=args.refraction)
    return options
