"""The instrument's figures from one or two ``hftrace reproduce`` runs: wall time, the
timed share of the measure phase, the half-widths of the first-hit group ratios, and how
many of the second run's ratios fall inside the first run's 95 % intervals
(docs/METHOD.md, "Paired rounds").

    python -m bench.studies.instrument_figures results/reproduce results/reproduce.2
"""
from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

from .. import analysis

#: The half-width (fraction of the speedup) a group ratio is counted against.
HALF_WIDTH = 0.03


def _ratios(run_dir):
    """The first-hit group ratios of a run (every kernel but the baseline, no errors)."""
    df = analysis.load(os.path.join(run_dir, "results.csv"))
    part = df[(df["workload"] == "first_hit") & (df["algorithm"] != "dda") & (df["error"] == "")]
    return part.set_index(["dataset", "surface", "run_length", "algorithm"])


def run_figures(run_dir) -> dict:
    """One run's figures: ``wall_s``, ``timed_share_of_measure``, the load (the noise
    calibration's and the groups' range), the number of group ratios, the median and
    90th-percentile half-width, the share within :data:`HALF_WIDTH`, and the contended
    groups."""
    part = _ratios(run_dir)
    with open(os.path.join(run_dir, "env.json")) as f:
        env = json.load(f)
    half = ((part["speedup_ci_high"] - part["speedup_ci_low"]) / (2 * part["speedup"])).to_numpy()
    half = half[np.isfinite(half)]
    groups = part.reset_index().drop_duplicates(["dataset", "surface", "run_length"])
    return {
        "run": run_dir, "wall_s": (env.get("reproduce") or {}).get("wall_s"),
        "timed_share_of_measure": env.get("timed_share_of_measure"),
        "noise_load": (env.get("noise") or {}).get("load"),
        "load_min": float(groups["load_before"].min()) if "load_before" in groups else None,
        "load_max": float(groups["load_after"].max()) if "load_after" in groups else None,
        "ratios": int(len(half)),
        "median_half_width": float(np.median(half)) if len(half) else None,
        "p90_half_width": float(np.percentile(half, 90)) if len(half) else None,
        "share_within": float(np.mean(half <= HALF_WIDTH)) if len(half) else None,
        "contended_groups": int(groups["contended"].sum()), "groups": int(len(groups)),
    }


def inside(first_dir, second_dir) -> dict:
    """How many of the second run's group ratios lie inside the first run's 95 %
    intervals (matched by dataset, surface, run length and kernel): ``inside``. Even two
    runs of a perfect instrument put only about 83 % there, since the second estimate
    carries its own noise (the difference of two estimates has sqrt(2) times the spread
    of one); ``consistent`` is the share whose two log-speedups differ by at most their
    two 95 % half-widths combined in quadrature (on the log scale), about 95 % for
    intervals that cover as they claim."""
    a, b = _ratios(first_dir), _ratios(second_dir)
    common = a.index.intersection(b.index)
    s = b.loc[common, "speedup"].to_numpy(float)
    lo = a.loc[common, "speedup_ci_low"].to_numpy(float)
    hi = a.loc[common, "speedup_ci_high"].to_numpy(float)
    s1 = a.loc[common, "speedup"].to_numpy(float)
    lo2 = b.loc[common, "speedup_ci_low"].to_numpy(float)
    hi2 = b.loc[common, "speedup_ci_high"].to_numpy(float)
    ok = np.isfinite(s) & np.isfinite(lo) & np.isfinite(hi) & np.isfinite(lo2) & np.isfinite(hi2)
    if not ok.any():
        return {"matched": 0, "inside": None, "consistent": None}
    # half-widths of the log-speedups (the intervals are symmetric in the log)
    h1 = np.log(hi[ok] / lo[ok]) / 2
    h2 = np.log(hi2[ok] / lo2[ok]) / 2
    gap = np.abs(np.log(s[ok]) - np.log(s1[ok]))
    return {"matched": int(ok.sum()),
            "inside": float(np.mean((lo[ok] <= s[ok]) & (s[ok] <= hi[ok]))),
            "consistent": float(np.mean(gap <= np.hypot(h1, h2)))}


def main(argv=None) -> int:
    """``python -m bench.studies.instrument_figures RUN [RUN2]``: prints the figures as
    JSON."""
    p = argparse.ArgumentParser(prog="python -m bench.studies.instrument_figures",
                                description="the instrument's figures of reproduce runs")
    p.add_argument("runs", nargs="+", help="one or two run directories (results.csv, env.json)")
    args = p.parse_args(argv)
    if len(args.runs) > 2:
        p.error(f"runs: expected one or two run directories, got {len(args.runs)}")
    for run in args.runs:
        for name in ("results.csv", "env.json"):
            if not os.path.isfile(os.path.join(run, name)):
                p.error(f"runs: {run} has no {name} (not a reproduce run directory)")
    out = {"runs": [run_figures(run) for run in args.runs]}
    if len(args.runs) == 2:
        out["second_inside_first"] = inside(*args.runs)
    print(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
