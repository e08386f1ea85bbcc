"""Tables and plots from any results.csv (``hftrace plot``, ``hftrace reproduce``).

Speedups are aggregated over datasets by the geometric mean (the mean of ratios that
treats 2x and 0.5x symmetrically); per-dataset tables keep each row's own interval.
Every cell and written conclusion is labelled by :func:`finding` (docs/METHOD.md,
"Labels" under "Paired rounds").
"""
from __future__ import annotations

import csv
import io
import json
import os
import sys

import numpy as np
import pandas as pd

from .cost_report import cost_model  # noqa: F401  (the report's section; analysis API)
from .findings import DEFAULT_PRECISION, REASONS, finding, ratio_text, verdict  # noqa: F401
from .report import PAPER, PLOT_KERNELS, PRIMARY, _geomean, _r_value, paired_design, results_row_check, scan_csv  # noqa: F401  (analysis API)

#: The headline table's columns at most (the full table goes to a second file).
HEADLINE_COLUMNS = 8
#: The paper's kernel (Henning & Stephenson 2004's run walk): always a headline column.
PAPER_KERNELS = ("runs",)


def group_label(rows) -> dict:
    """The inputs of :func:`finding` for the rows of one cell (one or more groups, e.g.
    one per dataset): geometric means of the speedup and of its bounds, the largest
    precision asked, contended when any group was, and the stop ``budget`` when any
    group's budget ran out (else ``rounds`` when any stopped on rounds)."""
    def column(name, default):
        return rows[name] if name in rows else pd.Series([default] * len(rows), index=rows.index)

    stops = set(column("stop", "").fillna("").astype(str))
    stop = "budget" if "budget" in stops else ("rounds" if stops - {"precision"} else "precision")
    precision = pd.to_numeric(column("precision", DEFAULT_PRECISION), errors="coerce")
    precision = float(precision.max()) if precision.notna().any() else DEFAULT_PRECISION
    return {"speedup": _geomean(rows["speedup"]), "low": _geomean(rows["speedup_ci_low"]),
            "high": _geomean(rows["speedup_ci_high"]), "precision": precision,
            "contended": bool(column("contended", False).astype(bool).any()), "stop": stop}


def _warn(text):
    print(text, file=sys.stderr)


def load(path, run=None, echo=_warn) -> pd.DataFrame:
    """A results.csv as a DataFrame: run lengths kept as text ("random" among numbers),
    the 2D workloads' empty surface as "-". Rows of different runs are never blended.

    Parameters
    ----------
    path : str
    run : str, optional
        The run to read: a prefix of its ``run_id`` (files without that column: of its
        ``commit``). Needed when the file holds more than one run.
    echo : callable or None
        Receives one line per damaged line of the file (a row a kill cut short, a
        malformed row, a repeated header), which is left out; default: standard error.

    Returns
    -------
    DataFrame
        ``df.attrs["runs"]``: the run read, as a list of one dict (``run_id``, ``commit``,
        ``machine``, ``started``, ``rows``); ``df.attrs["bad_lines"]``: the damaged lines
        as (line number, reason).

    Raises
    ------
    ValueError
        The file is missing or not a results.csv; it holds several runs and ``run`` is
        not given (the message lists them); ``run`` names none of them.
    """
    if not os.path.isfile(path):
        raise ValueError(f"results: {path} does not exist")
    try:
        header, rows, bad = scan_csv(path, ("algorithm", "workload", "dataset", "run_length"),
                                     results_row_check())
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"results: {path} is not a readable CSV ({exc})") from None
    needed = {"algorithm", "workload", "surface", "dataset", "run_length", "speedup",
              "speedup_ci_low", "speedup_ci_high", "ns_per_ray", "agree"}
    missing = sorted(needed - set(header))
    if missing:
        raise ValueError(f"results: {path} is not a results.csv of hftrace (no column "
                         f"{', '.join(missing)})")
    for number, reason in bad:
        if echo:
            echo(f"warning: results: line {number} of {path}: {reason}; left out")
    if not rows and bad:
        raise ValueError(f"results: {path} has no whole row: all {len(bad)} lines are "
                         f"damaged (line {bad[0][0]}: {bad[0][1]})")
    text = io.StringIO()
    writer = csv.writer(text)
    writer.writerow(header)
    writer.writerows([row[c] for c in header] for row in rows)
    text.seek(0)
    df = pd.read_csv(text, dtype={"run_length": str, "surface": str, "run_id": str,
                                  "commit": str, "machine": str, "started": str})
    df, runs = _one_run(df, path, run)
    df.attrs.update(runs=runs, bad_lines=bad)
    df["surface"] = df["surface"].fillna("-")
    if "contended" in df.columns:
        df["contended"] = df["contended"].astype(str).str.lower().isin(("true", "1"))
    else:
        df["contended"] = False
    if "error" not in df.columns:
        df["error"] = ""
    df["error"] = df["error"].astype(object).fillna("").astype(str)
    return df


def _run_key(df):
    """Each row's run: its ``run_id``, or where that is missing (files written before
    runs were identified, studies that write no identifier) its ``commit``; "" when
    neither is known."""
    empty = pd.Series([""] * len(df), index=df.index)
    commit = df["commit"].fillna("").astype(str) if "commit" in df.columns else empty
    run_id = df["run_id"].fillna("").astype(str) if "run_id" in df.columns else empty
    return run_id.where(run_id != "", commit)


def _one_run(df, path, run):
    """The rows of one run and its description; ValueError when ``df`` holds several
    and ``run`` does not choose one (results of two runs are never blended)."""
    keys = _run_key(df)
    runs = []
    for key in dict.fromkeys(keys):
        part = df[keys == key]
        first = part.iloc[0]
        runs.append({"run_id": str(first.get("run_id", "") if "run_id" in df else ""),
                     "commit": str(first.get("commit", "") if "commit" in df else ""),
                     "machine": str(first.get("machine", "") if "machine" in df else ""),
                     "started": str(first.get("started", "") if "started" in df else ""),
                     "key": key, "rows": len(part)})
    for r in runs:
        for field in ("run_id", "commit", "machine", "started"):
            r[field] = "" if r[field] == "nan" else r[field]
    if run is not None:
        chosen = [r for r in runs if r["key"] and r["key"].startswith(str(run))]
        if len(chosen) != 1:
            raise ValueError(f"--run: {run!r} names {'none' if not chosen else 'several'} of "
                             f"the {len(runs)} run(s) in {path}: {describe_runs(runs)}")
        return df[keys == chosen[0]["key"]].copy(), chosen
    if len(runs) > 1:
        raise ValueError(f"results: {path} holds {len(runs)} runs, which are never blended: "
                         f"{describe_runs(runs)}; choose one with --run ID")
    return df, runs


def describe_runs(runs) -> str:
    """``run 1a2b3c4d5e6f (commit 0123456789, machine host, started ...; 40 rows)``, ..."""
    out = []
    for r in runs:
        name = r["run_id"] or (f"commit {r['commit']}" if r["commit"] else "unidentified")
        facts = [f"commit {r['commit'][:10]}" if r["run_id"] and r["commit"] else "",
                 f"machine {r['machine']}" if r["machine"] else "",
                 f"started {r['started']}" if r["started"] else ""]
        facts = ", ".join(f for f in facts if f)
        out.append(f"run {name} ({facts + '; ' if facts else ''}{r['rows']} rows)")
    return "; ".join(out)


def _r_label(r):
    v = _r_value(r)
    return "random" if not np.isfinite(v) else (f"{v:g}")


def pivot(df, workload, surface, value="speedup"):
    """rows: run length; columns: algorithm; geometric mean over datasets."""
    part = df[(df["workload"] == workload) & (df["surface"] == surface)]
    if part.empty:
        return pd.DataFrame()
    table = part.groupby(["run_length", "algorithm"], sort=False)[value].apply(_geomean).unstack()
    table = table.loc[sorted(table.index, key=_r_value)]
    order = list(dict.fromkeys(part["algorithm"]))
    return table[[c for c in order if c in table.columns]]


def pivot_ci(df, workload, surface, columns=None) -> pd.DataFrame:
    """Like :func:`pivot`, each cell the text of :func:`ratio_text` for the cell's groups
    (:func:`group_label`: geometric means over datasets of the speedup and of its
    interval's bounds, an interval for the typical dataset), labelled by
    :func:`finding`. ``columns``: the algorithms to keep, in that order (default all)."""
    part = df[(df["workload"] == workload) & (df["surface"] == surface)]
    if part.empty:
        return pd.DataFrame()
    cells = {}
    for (r, name), g in part.groupby(["run_length", "algorithm"], sort=False):
        if name == "dda":
            text = "1 (baseline)"
        else:
            ok = g[g["error"] == ""] if (g["error"] != "").any() else g
            label = group_label(ok)
            text = ratio_text(label["speedup"], label["low"], label["high"], label["precision"],
                              label["contended"], label["stop"])
        if not text and (g["error"] != "").any():
            text = "error"
        cells.setdefault(name, {})[r] = text
    table = pd.DataFrame(cells)
    table = table.loc[sorted(table.index, key=_r_value)]
    if columns is not None:
        table = table[[c for c in columns if c in table.columns]]
    return table.fillna("")


def headline_kernels(df, workload="first_hit", surface="triangles",
                     limit=HEADLINE_COLUMNS) -> list:
    """The headline table's kernel columns, at most ``limit``: the paper's kernels
    (:data:`PAPER_KERNELS`), the fastest kernel of each family (the registry's ``kind``;
    geometric mean of the speedup over the table's groups), Embree (the fastest peer),
    then plugins while there is room; in the order of the rows."""
    import algos

    part = df[(df["workload"] == workload) & (df["surface"] == surface) & (df["algorithm"] != "dda")]
    present = list(dict.fromkeys(part["algorithm"]))
    speed = {n: _geomean(part.loc[part["algorithm"] == n, "speedup"]) for n in present}
    registry = algos.INTERSECTOR_REGISTRY if workload == "first_hit" else algos.TRAVERSAL_REGISTRY
    chosen = [n for n in PAPER_KERNELS if n in present]
    families, plugins = {}, []
    for n in present:
        entry = registry.get(n)
        if entry is None or getattr(entry, "plugin", None) is not None:
            plugins.append(n)
            continue
        families.setdefault(getattr(entry, "kind", n), []).append(n)
    peers = families.pop("peer", [])
    for members in families.values():
        ranked = [n for n in members if np.isfinite(speed[n])] or members
        best = max(ranked, key=lambda n: speed[n] if np.isfinite(speed[n]) else -1.0)
        if best not in chosen:
            chosen.append(best)
    if peers:
        ranked = [n for n in peers if np.isfinite(speed[n])] or peers
        chosen.append(max(ranked, key=lambda n: speed[n] if np.isfinite(speed[n]) else -1.0))
    chosen += [n for n in plugins if n not in chosen]
    # the room left goes to the other kernels, fastest first
    rest = sorted((n for n in present if n not in chosen),
                  key=lambda n: -speed[n] if np.isfinite(speed[n]) else np.inf)
    keep = set((chosen + rest)[:limit])
    return [n for n in present if n in keep]


def _markdown(table, first="r", paper=False, fmt="{:.2f}"):
    cols = list(table.columns)
    head = [first] + (["paper"] if paper else []) + cols
    lines = ["| " + " | ".join(head) + " |", "|---" * len(head) + "|"]
    for idx, row in table.iterrows():
        cells = [_r_label(idx) if first == "r" else str(idx)]
        if paper:
            key = "random" if _r_label(idx) == "random" else _r_value(idx)
            cells.append(fmt.format(PAPER[key]) if key in PAPER else "")
        cells += [v if isinstance(v, str) else (fmt.format(v) if np.isfinite(float(v)) else "")
                  for v in row.values]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def targets(df) -> list[str]:
    """The issue's targets, met or missed, with the numbers that decide."""
    out = []
    table = pivot(df, *PRIMARY)
    if table.empty:
        return ["- no first_hit/triangles rows: targets not evaluated"]

    lows = pivot(df, *PRIMARY, value="speedup_ci_low")
    highs = pivot(df, *PRIMARY, value="speedup_ci_high")

    def value(r, name, t=table):
        for idx in t.index:
            if _r_label(idx) == r and name in t.columns:
                return float(t.loc[idx, name])
        return np.nan

    runs_names = [n for n in ("runs", "runs_maxmip") if n in table.columns]
    if runs_names:
        for r, goal, word in (("25", 1.8, "at r = 25"), ("random", 1.25, "over random azimuths"),
                              ("1", 1.0, "at r = 1 (not slower)")):
            best = max(runs_names, key=lambda n: value(r, n) if np.isfinite(value(r, n)) else -1)
            v, lo, hi = value(r, best), value(r, best, lows), value(r, best, highs)
            if np.isfinite(v):
                rows = df[(df["workload"] == PRIMARY[0]) & (df["surface"] == PRIMARY[1]) &
                          (df["algorithm"] == best) & (df["run_length"].map(_r_label) == r)]
                label = group_label(rows)
                said = finding(v, lo, hi, label["precision"], label["contended"], label["stop"])
                if said.startswith("inconclusive"):
                    decided = f"inconclusive ({said.split(': ', 1)[1]})"
                elif lo <= goal <= hi:
                    decided = "inconclusive (the interval contains the target)"
                else:
                    decided = "met" if v >= goal else "missed"
                out.append(f"- `{best}` {word}: {v:.2f}x [{lo:.2f}, {hi:.2f}] dda (target >= "
                           f"{goal}): **{decided}**")
    if "embree" in table.columns:
        exact = [n for n in table.columns if n in _exact_names()]
        ratios = []
        for idx in table.index:
            e = table.loc[idx, "embree"]
            best = max(table.loc[idx, n] for n in exact)
            ratios.append(best / e)
        v = _geomean(ratios)
        primary = df[(df["workload"] == PRIMARY[0]) & (df["surface"] == PRIMARY[1])]
        decided = ("inconclusive (contended)" if bool(primary["contended"].any())
                   else ("met" if v >= 2 else "missed"))
        out.append(f"- best exact kernel vs Embree (rays/s, geometric mean over r): {v:.2f}x "
                   f"(target >= 2): **{decided}**")
    return out


def _exact_names():
    import algos

    return {n for n, a in algos.INTERSECTOR_REGISTRY.items() if a.accuracy == "exact"}


CELL_WALKS = ("dda", "dda_f32", "midpoint")


def fair_baseline(df, workload="first_hit", surface="triangles") -> pd.DataFrame:
    """Per run length: which cell walk is fastest, and every run kernel's speedup over it,
    over dda and over midpoint (geometric means over datasets of per-group ratios)."""
    part = df[(df["workload"] == workload) & (df["surface"] == surface)]
    if part.empty or "midpoint" not in set(part["algorithm"]):
        return pd.DataFrame()
    runs = [n for n in ("runs", "runs_f64", "runs_periodic", "runs_maxmip")
            if n in set(part["algorithm"])]
    out = {}
    for r, group in part.groupby("run_length", sort=False):
        row, winners = {}, []
        ratios = {f"{n} / {b}": [] for n in runs for b in ("fastest", "dda", "midpoint")}
        for _, g in group.groupby("dataset", sort=False):
            speed = dict(zip(g["algorithm"], g["speedup"].astype(float)))
            cells = {n: speed[n] for n in CELL_WALKS if n in speed}
            best = max(cells, key=cells.get)
            winners.append(best)
            for n in runs:
                if n in speed:
                    ratios[f"{n} / fastest"].append(speed[n] / cells[best])
                    ratios[f"{n} / dda"].append(speed[n])
                    ratios[f"{n} / midpoint"].append(speed[n] / speed["midpoint"])
        row["fastest cell walk"] = "/".join(sorted(set(winners)))
        for key, values in ratios.items():
            row[key] = _geomean(values) if values else float("nan")
        out[_r_label(r)] = row
    table = pd.DataFrame(out).T
    order = sorted(table.index, key=lambda x: _r_value(x))
    return table.loc[order]


def summary_lines(df, env=None) -> list:
    """The report's first lines: what the cells found, whether the run was contended, and
    the noise floor with the load (``env["noise"]``, ``bench.sweep.calibrate_noise``)."""
    part = df[(df["algorithm"] != "dda") & (df["error"] == "")]
    if part.empty:
        return []
    labels = [finding(s, lo, hi, p, c, st) for s, lo, hi, p, c, st in zip(
        part["speedup"], part["speedup_ci_low"], part["speedup_ci_high"],
        part["precision"] if "precision" in part else [DEFAULT_PRECISION] * len(part),
        part["contended"], part["stop"].fillna("") if "stop" in part else [""] * len(part))]
    words = pd.Series([w.split(" within")[0] for w in labels]).value_counts()
    groups = df.drop_duplicates(["dataset", "workload", "surface", "run_length"])
    n, bad = len(groups), int(groups["contended"].sum())
    lines = []
    if n and bad == n:
        lines.append(f"**Every group ({n}) ran while other processes used the machine: no "
                     "cell is a finding. Rerun on a quiet machine.**")
    elif bad:
        lines.append(f"{bad} of {n} groups ran while other processes used the machine; their "
                     "cells are labelled contended.")
    lines.append("Group ratios: " + ", ".join(f"{k} {v}" for k, v in words.items()) +
                 f" (of {len(labels)}).")
    noise = (env or {}).get("noise")
    if noise:
        lines.append(f"Noise floor: one pair's log-ratio spreads by "
                     f"{100 * noise['log_sd']:.1f} % (A/A: the baseline against itself, "
                     f"{noise['pairs']} pairs of {noise['call_rays']}-ray calls; 1.4826 MAD), "
                     f"so {noise['rounds_affordable']} pairs, what a group affords a kernel in "
                     f"its budget, resolve ±{100 * noise['floor']:.1f} %; "
                     f"load average {noise.get('load')}.")
        asked = (env.get("run") or {}).get("precision")
        if asked and noise["floor"] > asked:
            lines.append(f"The floor is above the precision asked (±{100 * asked:.0f} %): "
                         "cells that do not reach it are labelled, not reported as findings.")
    return lines + [""]


def _cell_texts(part):
    """The per-row cell texts of :func:`ratio_text` (one group each); ``error`` for a row
    with an error, as :func:`pivot_ci` gives it (a wrong exactness claim keeps its
    timings, which are no finding)."""
    precision = part["precision"] if "precision" in part else [DEFAULT_PRECISION] * len(part)
    stops = part["stop"].fillna("") if "stop" in part else [""] * len(part)
    errors = part["error"] if "error" in part else [""] * len(part)
    return ["1 (baseline)" if a == "dda" else "error" if e else
            ratio_text(s, lo, hi, p, c, st)
            for a, s, lo, hi, p, c, st, e in zip(part["algorithm"], part["speedup"],
                                                 part["speedup_ci_low"],
                                                 part["speedup_ci_high"], precision,
                                                 part["contended"], stops, errors)]


CELL_LEGEND = ("Each cell: speedup ±half-width of its 95 % interval, in percent of the "
               "speedup (geometric means over datasets of the groups' paired ratios and "
               "bounds; docs/METHOD.md). A cell is a finding when the half-width is within "
               "the precision asked: faster (interval above 1), slower (below 1), or "
               "`(same)` (it contains 1). Otherwise the reason is in parentheses: "
               "`contended` (other processes used the machine; never a finding), `budget "
               "spent` or `too few repeats`.")


def _table_text(text) -> str:
    """``text`` as one Markdown table cell: on one line, its pipes escaped (a kernel's
    error message may hold either, which would break the table's row)."""
    return " ".join(str(text).split()).replace("|", "\\|")


def speedup_markdown(df, env=None, title="hftrace reproduce", counts=None,
                     full=False) -> str:
    """The Markdown report of a sweep's rows ``df``: what was found and the noise floor
    (:func:`summary_lines`), the machine (``env``), the paper's measure (the headline
    table: :func:`headline_kernels`, or every kernel with ``full``), one speedup table per
    workload and surface (geometric mean over datasets) and, with ``counts`` (kernel ->
    counts.csv row), the cost model."""
    lines = [f"# {title}: speedup over `dda`", ""] + summary_lines(df, env)
    if env:
        lines += [f"Machine: {env.get('cpu')} ({env.get('cores')} cores, one used), Python "
                  f"{env.get('python')}, NumPy {env.get('numpy')}, commit "
                  f"`{env.get('git_commit')}`.", ""]
    runs = df.attrs.get("runs")
    if runs:
        lines += [f"Rows of {describe_runs(runs)}.", ""]
    datasets = list(dict.fromkeys(df["dataset"]))
    rounds = pd.to_numeric(df["rounds"], errors="coerce") if "rounds" in df else None
    if rounds is None or rounds.isna().all():  # results of the fixed-repeats design
        rounds = pd.to_numeric(df["repeats"], errors="coerce")
    calls = sorted(set(df["call_rays"].dropna().astype(int))) if "call_rays" in df else []
    paired = paired_design(df)
    if paired and "algorithm" in df:  # the baseline's own count is of its visits
        rounds = rounds[(df["algorithm"] != "dda").to_numpy()]
    how = ("the median over adjacent pairs (each kernel's call between two of dda's) of time "
           "of dda / time of the algorithm" if paired else
           "geometric mean over paired rounds of time of dda / time of the algorithm")
    lines += [f"Datasets: {', '.join(datasets)}. Rays per timed call: "
              f"{', '.join(map(str, calls or sorted(set(df['rays']))))}; "
              f"{'pairs' if paired else 'rounds'} per kernel: "
              f"{int(np.nanmin(rounds))} to {int(np.nanmax(rounds))}. Speedup = {how} on the "
              "same rays in the same process (docs/METHOD.md); tables aggregate datasets by "
              "the geometric mean.", ""]
    table = pivot(df, *PRIMARY)
    if not table.empty:
        from .report import EMBREE_NOTE, axes_caption

        # the headline names its regime: the sweep's rows record it (older CSVs: flushed, random)
        regimes = sorted(set(df["regime"].dropna())) if "regime" in df else []
        coherences = sorted(set(df["coherence"].dropna())) if "coherence" in df else []
        # rows of several regimes or coherences (results.csv files put together by hand)
        # are said to be mixed, never captioned as one of them
        caption = axes_caption(
            regimes[0] if len(regimes) == 1 else
            f"mixed ({', '.join(regimes)}; each row's `regime` says which)" if regimes else
            "flushed",
            coherences[0] if len(coherences) == 1 else
            f"mixed ({', '.join(coherences)})" if coherences else "random")
        embree = f" {EMBREE_NOTE}." if any(str(a).startswith("embree") for a in df["algorithm"]) else ""
        shown = None if full else headline_kernels(df)
        scope = ("every kernel measured" if full else
                 "the paper's kernel, the fastest of each family and Embree; every kernel "
                 "in `speedup_full.md`")
        lines += ["## The paper's measure: first hit on triangles, by mean run length", "",
                  caption + embree, "", CELL_LEGEND + f" Columns: {scope}.", "",
                  _markdown(pivot_ci(df, *PRIMARY, columns=shown), paper=True), ""]
        part = df[(df["workload"] == PRIMARY[0]) & (df["surface"] == PRIMARY[1]) &
                  (df["run_length"] == "random")]
        if shown is not None:
            part = part[part["algorithm"].isin(shown)]
        if not part.empty:
            part = part.assign(text=_cell_texts(part))
            by_ds = part.pivot(index="dataset", columns="algorithm", values="text").fillna("")
            by_ds = by_ds.loc[list(dict.fromkeys(part["dataset"]))]
            by_ds = by_ds[[c for c in dict.fromkeys(part["algorithm"]) if c in by_ds.columns]]
            lines += ["## By dataset: first hit on triangles over random azimuths", "",
                      _markdown(by_ds, first="dataset"), ""]
    fair = fair_baseline(df)
    if not fair.empty:
        lines += ["## Against the fastest cell walk (the fair baseline), first hit on triangles",
                  "",
                  "In each group the fastest of the per-cell walks (`dda`, `dda_f32`, "
                  "`midpoint`) is the baseline; each run kernel's speedup over it, over `dda` "
                  "and over `midpoint` (ratios of the same groups' medians, geometric mean over "
                  "datasets). The paper's claim compares runs with a cell walk doing the same "
                  "per-cell test; this is that claim against a competent baseline.", "",
                  _markdown(fair, paper=True), ""]
    lines += ["## Targets", ""] + targets(df) + [""]
    lines += ["`runs_periodic` rebuilds its run pattern whenever the direction changes; the "
              "random-azimuth rays give every ray a new direction, its worst case (it is built "
              "for batches of parallel rays).", ""]
    for (workload, surface), _ in df.groupby(["workload", "surface"], sort=False):
        if (workload, surface) == PRIMARY:
            continue
        t = pivot_ci(df, workload, surface)
        label = workload if surface == "-" else f"{workload}, {surface}"
        lines += [f"## Workload: {label}", "",
                  "Each cell: speedup over dda [95 % interval], as in the first table.", "",
                  _markdown(t), ""]
    lines += cost_model(df, counts)
    lines += load_section(df, env)
    errors = df[df["error"] != ""]
    if not errors.empty:
        lines += ["## Kernel errors", "",
                  "These kernels failed or claimed exactness they did not have; their rows "
                  "have no speedup (a wrong exact claim keeps its timings). The other rows "
                  "are unaffected.", "", "| algorithm | dataset | workload | r | error |",
                  "|---|---|---|---|---|"]
        for _, row in errors.iterrows():
            lines.append(f"| {row['algorithm']} | {row['dataset']} | {row['workload']} | "
                         f"{_r_label(row['run_length'])} | {_table_text(row['error'])} |")
        lines.append("")
    agree = df[df["agree"] < 1.0]
    if not agree.empty:
        worst = agree.groupby("algorithm")["agree"].min()
        lines += ["## Agreement with the exact reference (lowest per algorithm)", "",
                  "| algorithm | lowest agreement |", "|---|---|"]
        lines += [f"| {a} | {100 * v:.2f} % |" for a, v in worst.items()]
        lines.append("")
    return "\n".join(lines)


def load_section(df, env=None) -> list:
    """The machine's load while the rows were measured (``bench.load``)."""
    if "other_cpu" not in df.columns or df["other_cpu"].isna().all():
        return []
    groups = df.drop_duplicates(["dataset", "workload", "surface", "run_length"])
    n, bad = len(groups), int(groups["contended"].sum())
    lines = ["## Load while measuring", "",
             f"{bad} of {n} groups ran under contention (other processes used more than "
             "0.5 cores on average, or the load average exceeded the CPUs; `bench/load.py`). "
             f"Other processes' CPU use: median {groups['other_cpu'].median():.2f} cores, "
             f"largest {groups['other_cpu'].max():.2f}; 1-minute load average from "
             f"{groups['load_before'].min():.2f} to {groups['load_after'].max():.2f}."]
    run = (env or {}).get("run")
    if run:
        sessions = (f" in {run['sessions']} sessions (resumed)"
                    if (run.get("sessions") or 1) > 1 else "")
        lines.append(f"The sweep took {run['wall_s']:.0f} s{sessions}, "
                     f"{100 * (run['timed_share'] or 0):.0f} % of it inside timed calls.")
        if run.get("timed_share_of_measure") is not None:
            prepared = (f" after {run['prepare_s']:.0f} s preparing the fields' structures"
                        if run.get("prepare_s") else "")
            lines.append(f"Measuring took {run['measure_s']:.0f} s{prepared}, "
                         f"{100 * run['timed_share_of_measure']:.0f} % of it inside timed calls "
                         f"and {run['flush_s']:.1f} s preparing the cache state (flushing, or "
                         "each visit's untimed warm call); "
                         f"{run.get('remeasured_groups', 0)} contended groups were measured "
                         "again.")
    if bad:
        lines.append("**Cells of contended groups are labelled `contended`, never findings; "
                     "rerun on a quiet machine before quoting them.**")
    return lines + [""]


def report_title(env) -> str:
    """The title of a run's reports, from its ``env.json``: the ``reproduce`` preset, else
    the sweep's name, else a neutral one (a file without either)."""
    env = env or {}
    preset = (env.get("reproduce") or {}).get("preset")
    if preset:
        return f"hftrace reproduce ({preset} preset)"
    if env.get("sweep_name"):
        return f"hftrace sweep {env['sweep_name']}"
    return "hftrace results"


def write_reports(csv_path, out_dir=None, title=None, all_kernels=False,
                  run=None, echo=_warn) -> dict:
    """speedup.md (the headline table), speedup_full.md (every kernel),
    run_length_vs_speedup.png and ns_per_ray_vs_cells.png from a CSV (``all_kernels``:
    every kernel in the plots, not the default subset), of one run (``run``: see
    :func:`load`). ``echo`` receives the run read and each damaged line left out.
    ``title`` heads the reports; by default :func:`report_title` of the ``env.json``
    beside the CSV, so `hftrace plot` never calls a sweep the reproduce study.
    ``ValueError`` when the CSV is missing, not a results.csv, or holds several runs and
    ``run`` does not choose one."""
    out_dir = out_dir or os.path.dirname(os.path.abspath(csv_path))
    df = load(csv_path, run=run, echo=echo)
    if echo:
        echo(f"read {describe_runs(df.attrs['runs'])} from {csv_path}")
    os.makedirs(out_dir, exist_ok=True)
    env_path = os.path.join(os.path.dirname(os.path.abspath(csv_path)), "env.json")
    try:
        env = json.load(open(env_path)) if os.path.exists(env_path) else None
    except (OSError, ValueError):
        env = None
    if title is None:
        title = report_title(env)
    paths = {"speedup": os.path.join(out_dir, "speedup.md"),
             "plot": os.path.join(out_dir, "run_length_vs_speedup.png"),
             "cost": os.path.join(out_dir, "ns_per_ray_vs_cells.png")}
    from .counts import read_counts
    from .plots import plot_cost, plot_speedup

    counts = read_counts(os.path.join(os.path.dirname(os.path.abspath(csv_path)), "counts.csv"))
    paths["full"] = os.path.join(out_dir, "speedup_full.md")
    with open(paths["speedup"], "w") as f:
        f.write(speedup_markdown(df, env, title, counts=counts))
    with open(paths["full"], "w") as f:
        f.write(speedup_markdown(df, env, title + ", every kernel", counts=counts, full=True))
    # the paper's measure when the rows hold it, else the first workload they hold
    pairs = list(dict.fromkeys(zip(df["workload"], df["surface"])))
    workload, surface = PRIMARY if PRIMARY in pairs or not pairs else pairs[0]
    plot_speedup(df, paths["plot"], workload, surface, all_kernels=all_kernels)
    plot_cost(df, paths["cost"], all_kernels=all_kernels)
    return paths
