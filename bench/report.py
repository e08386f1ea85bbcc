"""Shared pieces of the benchmark reports: the speedup table, the row writer, the
reader that finds the rows a kill cut short, and what the tables (:mod:`bench.analysis`)
and the plots (:mod:`bench.plots`) both read (the paper's figures, the kernels plotted,
the run-length order, the geometric mean, the rows' design)."""
from __future__ import annotations

import csv
import io
import math
import os

import numpy as np
import pandas as pd

from .findings import DEFAULT_PRECISION, ratio_text

#: Measured columns of a results.csv that hold a number when not empty ("nan" allowed):
#: a speedup, a time or an agreement that is text or negative was edited or corrupted.
MEASURED_COLUMNS = ("ns_per_ray", "ns_per_ray_ci_low", "ns_per_ray_ci_high", "speedup",
                    "speedup_ci_low", "speedup_ci_high", "agree")


def results_row_check():
    """A ``check`` for :func:`scan_csv` of a results.csv: the reason a whole row cannot
    be a measurement (a run length that is neither a positive number nor "random", a
    measured column that is not a non-negative number, an agreement outside [0, 1], or
    the very same row as an earlier line: a file appended to itself), or None."""
    seen = {}

    def check(row, line):
        r = row.get("run_length", "random")
        try:
            bad_r = r != "random" and not (math.isfinite(float(r)) and float(r) > 0)
        except ValueError:
            bad_r = True
        if bad_r:
            return f"malformed: run_length {r!r} is neither a positive number nor 'random'"
        for column in MEASURED_COLUMNS:
            text = row.get(column, "")
            if text == "":
                continue
            try:
                value = float(text)
            except ValueError:
                return f"malformed: {column} {text!r} is not a number"
            if value < 0 or (column == "agree" and value > 1):
                return f"malformed: {column} {text!r} is out of range"
        key = tuple(row.values())
        if key in seen:
            return f"repeats line {seen[key]} (the same measurement twice)"
        seen[key] = line
        return None

    return check


def scan_csv(path, required=(), check=None):
    """Read a CSV that :class:`RowWriter` wrote, telling whole rows from damaged lines.

    Parameters
    ----------
    path : str
        The CSV; a missing or empty file has no header and no rows.
    required : sequence of str
        Columns that must not be empty in a whole row.
    check : callable, optional
        ``check(row, line)`` -> the reason a whole row is damaged, or None
        (:func:`results_row_check`).

    Returns
    -------
    header : list of str
    rows : list of dict
        The whole rows, column -> text, in file order.
    bad : list of (int, str)
        Each damaged line's number (1-based, the header is line 1) and what is wrong: a
        last row without its line end (a kill mid-write), a row with another number of
        fields than the header, a required column left empty, a byte the CSV reader
        refuses, or the header repeated (files concatenated).
    """
    if not os.path.exists(path):
        return [], [], []
    # utf-8-sig: a file saved by a spreadsheet starts with a byte-order mark
    with open(path, newline="", encoding="utf-8-sig", errors="replace") as f:
        text = f.read()
    reader = csv.reader(io.StringIO(text))
    header, rows, bad = None, [], []
    records = []
    line = 0
    while True:
        start = line + 1
        try:
            record = next(reader)
        except StopIteration:
            break
        except csv.Error as exc:
            line = reader.line_num
            bad.append((start, f"unreadable ({exc})"))
            continue
        line = reader.line_num
        if header is None:
            header = record
            continue
        records.append((start, record))
    if header is None:
        return [], [], []
    for k, (start, record) in enumerate(records):
        if not record:
            continue  # a blank line
        last = k == len(records) - 1
        if last and not text.endswith(("\n", "\r")):
            bad.append((start, f"truncated: the row has no line end ({len(record)} of "
                               f"{len(header)} fields, the last one possibly cut), as a kill "
                               "mid-write leaves it"))
        elif record == header:
            bad.append((start, "repeats the header (two files concatenated?)"))
        elif len(record) != len(header):
            bad.append((start, f"malformed: {len(record)} fields, the header has {len(header)}"))
        else:
            row = dict(zip(header, record))
            empty = [c for c in required if c in row and row[c] == ""]
            reason = f"malformed: no {', '.join(empty)}" if empty else \
                (check(row, start) if check else None)
            if reason:
                bad.append((start, reason))
            else:
                rows.append(row)
    bad.sort()
    return header, rows, bad


class RowWriter:
    """Append result rows to a CSV, flushing each one, so an interrupted run keeps every
    row it measured.

    Appending to a file whose lines a kill damaged (:func:`scan_csv`) first moves those
    lines to ``<path>.rejected`` and rewrites the file with its whole rows, so that a new
    row never continues a cut one; :attr:`rejected` lists them as (line, reason)."""

    def __init__(self, path, columns, append=False, required=(), check=None):
        self.path = path
        self.columns = list(columns)
        self.rejected = []
        exists = append and os.path.exists(path) and os.path.getsize(path) > 0
        if exists:
            # as scan_csv reads it: a byte-order mark skipped, bytes that are not UTF-8
            # replaced (binary garbage is then a header mismatch naming the file)
            with open(path, newline="", encoding="utf-8-sig", errors="replace") as f:
                header = next(csv.reader(f), [])
            if header != self.columns:
                raise ValueError(
                    f"{path}: its columns {header} differ from this version's {self.columns}; "
                    "it was written by another version of hftrace, so rows cannot be appended "
                    "to it: choose another --out or start afresh")
            _, rows, self.rejected = scan_csv(path, required, check)
            if self.rejected:
                self._set_aside(rows)
        self._file = open(path, "a" if exists else "w", newline="")
        self._writer = csv.DictWriter(self._file, fieldnames=self.columns, extrasaction="ignore")
        if not exists:
            self._writer.writeheader()
            self._file.flush()

    def _set_aside(self, rows):
        """Move the damaged lines to ``<path>.rejected`` and rewrite the file with the
        header and the whole ``rows`` (their text unchanged)."""
        with open(self.path, newline="", errors="replace") as f:
            lines = f.read().splitlines(keepends=True)
        with open(self.path + ".rejected", "a", newline="") as f:
            for number, reason in self.rejected:
                text = lines[number - 1].rstrip("\r\n") if number <= len(lines) else ""
                f.write(f"# line {number} of {os.path.basename(self.path)}: {reason}\n{text}\n")
        partial = self.path + ".partial"
        with open(partial, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(self.columns)
            for row in rows:
                writer.writerow([row[c] for c in self.columns])
            f.flush()
            os.fsync(f.fileno())
        os.replace(partial, self.path)

    def write(self, row: dict) -> None:
        """Append ``row`` (extra keys ignored) and flush it to disk."""
        self._writer.writerow(row)
        self._file.flush()
        os.fsync(self._file.fileno())

    def close(self) -> None:
        """Close the file; every written row is already on disk."""
        self._file.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


#: What each cache regime and ray coherence means, for the captions of every speedup
#: table (docs/METHOD.md, "Cache regimes and coherence").
REGIME_TEXT = {"flushed": "caches flushed before every timed run",
               "flushed-per-call": "caches flushed before every timed call",
               "flushed-per-round": "caches flushed once per round of calls, kernels in a "
                                    "fresh random order each round",
               "unflushed": "caches never flushed, kernels in a fresh random order each round",
               "warm": "each kernel warmed on its own rays (an untimed run right before)"}
COHERENCE_TEXT = {"random": "random rays (origins over the field, azimuth atan(1/r), all octants)",
                  "parallel": "parallel rays (one direction of slope 1/r per batch)",
                  "camera": "camera rays (render's pinhole batch)",
                  "level": "camera rays (render's level projection, one plane per column)",
                  "orthographic": "camera rays (render's orthographic projection)"}
#: Said next to every Embree figure.
EMBREE_NOTE = ("`embree` is embreex, which reaches Embree's single-ray triangle queries only; "
               "`embree3`, where built (libembree-dev), is the C peer with Embree 3's grid "
               "geometry and packets, reported beside it")


def axes_caption(regime="flushed", coherence="random") -> str:
    """The caption naming a table's cache regime and ray coherence."""
    return (f"Cache regime: {REGIME_TEXT.get(regime, regime)}; rays: "
            f"{COHERENCE_TEXT.get(coherence, coherence)}.")


def speedup_table(rows, column_key="run_length", column_label="r", footer=None) -> str:
    """A Markdown table: one row per algorithm, one column per value of ``column_key``;
    each cell ``speedup ±half-width %`` labelled by ``bench.findings.finding`` (the
    rows' ``precision``, ``contended`` and ``stop`` where they record them), then ns/ray,
    plus the agreement when below 100 %."""

    columns = list(dict.fromkeys(row[column_key] for row in rows))
    names = list(dict.fromkeys(row["algorithm"] for row in rows))
    lookup = {(row["algorithm"], row[column_key]): row for row in rows}
    lines = ["| algorithm | " + " | ".join(f"{column_label}={c}" for c in columns) + " |",
             "|---" * (len(columns) + 1) + "|"]
    for name in names:
        cells = []
        for c in columns:
            row = lookup.get((name, c))
            if row is None:
                cells.append("")
                continue
            agree = float(row["agree"])
            flag = "" if agree == 1.0 else f" ({100 * agree:.2f} % agree)"
            contended = str(row.get("contended", "")).lower() in ("true", "1")
            precision = row.get("precision") or DEFAULT_PRECISION
            text = ("1 (baseline)" if row["algorithm"] == row.get("baseline", "dda") else
                    ratio_text(row["speedup"], row["speedup_ci_low"], row["speedup_ci_high"],
                               precision, contended, row.get("stop", "")))
            cells.append(f"{text}, {float(row['ns_per_ray']):.0f} ns{flag}")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    if footer and footer(columns, lookup, names):
        lines.append(footer(columns, lookup, names))
    if any(name.startswith("embree") for name in names):
        lines += ["", EMBREE_NOTE + "."]
    return "\n".join(lines)


#: Henning & Stephenson 2004 as summarised in the seeds: speedup of the run walk over the
#: cell walk by mean run length, and over all orientations.
PAPER = {1.0: 1.0, 2.0: 1.1, 25.0: 1.8, "random": 1.25}
PRIMARY = ("first_hit", "triangles")

#: The kernels the plots show by default (plugins always join them; ``all_kernels``
#: shows every one).
PLOT_KERNELS = ("dda_f32", "midpoint", "runs", "runs_maxmip", "dda_maxmip", "embree")


def _r_value(r):
    try:
        return float(r)
    except (TypeError, ValueError):
        return np.inf  # "random" sorts last


def _geomean(values):
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values) & (values > 0)]
    return float(np.exp(np.mean(np.log(values)))) if len(values) else np.nan


def paired_design(df) -> bool:
    """Whether the rows were measured in adjacent pairs with a precision (docs/METHOD.md,
    "Paired rounds"), whose speedup is the median pair's ratio; else the fixed-repeats
    design, whose speedup is the geometric mean of the paired per-round ratios."""
    return bool("regime" in df and df["regime"].isin(["warm", "flushed-per-call",
                                                       "flushed-per-round", "unflushed"]).any()
                and "precision" in df
                and pd.to_numeric(df["precision"], errors="coerce").notna().any())
