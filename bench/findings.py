"""The one labelling rule of every table and written conclusion: what a ratio's 95 %
interval says (docs/METHOD.md, "Labels" under "Paired rounds").

Below both the table writers (``bench.report``) and the analysis of results files
(``bench.analysis``, which re-exports these names), so neither imports the other.
"""
from __future__ import annotations

import numpy as np

#: The precision a ratio's 95 % interval must reach to be a finding when its rows do not
#: record one (results of the fixed-repeats design): ±2 % of the speedup.
DEFAULT_PRECISION = 0.02
#: Why a cell is inconclusive, by the ``stop`` of its rows (``bench.timing.STOPS``).
REASONS = {"budget": "budget spent", "rounds": "too few repeats", "precision": "too few repeats",
           "": "too few repeats"}

def finding(speedup, low, high, precision=DEFAULT_PRECISION, contended=False,
            stop="") -> str:
    """What a ratio's 95 % interval ``[low, high]`` says, the one rule of every table and
    written conclusion (docs/METHOD.md, "Labels").

    A cell is a finding when its half-width (:func:`bench.timing.relative_half_width`) is
    at most ``precision`` (a fraction; 0.02 is ±2 %) and its group was not ``contended``:
    ``"faster"`` (the interval lies above 1), ``"slower"`` (below 1) or ``"same within
    ±x %"`` (it contains 1; x is the farthest bound's distance from 1, in percent). Any
    other cell is ``"inconclusive: "`` and the reason: ``contended`` (other processes
    used the machine: never a finding, whatever the interval), else, by the rows'
    ``stop``, ``budget spent`` or ``too few repeats`` (also when the interval is missing).
    """
    from .timing import relative_half_width

    if contended:
        return "inconclusive: contended"
    half = relative_half_width(speedup, low, high)
    try:
        precision = float(precision)
    except (TypeError, ValueError):
        precision = DEFAULT_PRECISION
    if not np.isfinite(precision) or precision <= 0:
        precision = DEFAULT_PRECISION
    if not np.isfinite(half) or half > precision + 1e-12:
        return "inconclusive: " + REASONS.get(str(stop or ""), "too few repeats")
    lo, hi = float(low), float(high)
    if lo > 1.0:
        return "faster"
    if hi < 1.0:
        return "slower"
    return f"same within ±{100 * max(hi - 1.0, 1.0 - lo):.1f} %"


def verdict(speedup, low, high, precision=DEFAULT_PRECISION, contended=False, stop="") -> str:
    """The word of :func:`finding`: ``"faster"``, ``"slower"``, ``"same"`` or
    ``"inconclusive"``."""
    return finding(speedup, low, high, precision, contended, stop).split(" ")[0].rstrip(":")


def ratio_text(speedup, low, high, precision=DEFAULT_PRECISION, contended=False, stop="",
               fmt="{:.2f}") -> str:
    """A cell: ``1.53 ±1.8 %`` (the speedup and its interval's half-width in percent of
    it), then ``(same)`` or, for an inconclusive cell, the reason in parentheses, from
    :func:`finding`. Empty when the speedup is missing."""
    from .timing import relative_half_width

    if not np.isfinite(float(speedup)):
        return ""
    half = relative_half_width(speedup, low, high)
    text = fmt.format(float(speedup)) + (f" ±{100 * half:.1f} %" if np.isfinite(half) else "")
    label = finding(speedup, low, high, precision, contended, stop)
    if label.startswith("inconclusive"):
        return f"{text} ({label.split(': ', 1)[1]})"
    if label.startswith("same"):
        return f"{text} (same)"
    return text
