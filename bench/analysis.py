"""Tables and plots from any results.csv (``hftrace plot``, ``hftrace reproduce``).

Speedups are aggregated over datasets by the geometric mean (the mean of ratios that
treats 2x and 0.5x symmetrically); per-dataset tables keep each row's own bootstrap
interval.
"""
from __future__ import annotations

import json
import os

import numpy as np
import pandas as pd

#: Henning & Stephenson 2004 as summarised in the seeds: speedup of the run walk over the
#: cell walk by mean run length, and over all orientations.
PAPER = {1.0: 1.0, 2.0: 1.1, 25.0: 1.8, "random": 1.25}
PRIMARY = ("first_hit", "triangles")


def load(path) -> pd.DataFrame:
    """A results.csv as a DataFrame: run lengths kept as text ("random" among numbers),
    the 2D workloads' empty surface as "-"."""
    df = pd.read_csv(path, dtype={"run_length": str, "surface": str})
    df["surface"] = df["surface"].fillna("-")
    return df


def _r_value(r):
    try:
        return float(r)
    except (TypeError, ValueError):
        return np.inf  # "random" sorts last


def _r_label(r):
    v = _r_value(r)
    return "random" if not np.isfinite(v) else (f"{v:g}")


def _geomean(values):
    values = np.asarray(values, dtype=float)
    values = values[np.isfinite(values) & (values > 0)]
    return float(np.exp(np.mean(np.log(values)))) if len(values) else np.nan


def pivot(df, workload, surface, value="speedup"):
    """rows: run length; columns: algorithm; geometric mean over datasets."""
    part = df[(df["workload"] == workload) & (df["surface"] == surface)]
    if part.empty:
        return pd.DataFrame()
    table = part.groupby(["run_length", "algorithm"], sort=False)[value].apply(_geomean).unstack()
    table = table.loc[sorted(table.index, key=_r_value)]
    order = list(dict.fromkeys(part["algorithm"]))
    return table[[c for c in order if c in table.columns]]


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

    def value(r, name):
        for idx in table.index:
            if _r_label(idx) == r and name in table.columns:
                return float(table.loc[idx, name])
        return np.nan

    runs_names = [n for n in ("runs", "runs_maxmip") if n in table.columns]
    if runs_names:
        for r, goal, word in (("25", 1.8, "at r = 25"), ("random", 1.25, "over random azimuths"),
                              ("1", 1.0, "at r = 1 (not slower)")):
            best = max(runs_names, key=lambda n: value(r, n) if np.isfinite(value(r, n)) else -1)
            v = value(r, best)
            if np.isfinite(v):
                out.append(f"- `{best}` {word}: {v:.2f}x dda (target >= {goal}): "
                           f"**{'met' if v >= goal else 'missed'}**")
    if "embree" in table.columns:
        exact = [n for n in table.columns if n in _exact_names()]
        ratios = []
        for idx in table.index:
            e = table.loc[idx, "embree"]
            best = max(table.loc[idx, n] for n in exact)
            ratios.append(best / e)
        v = _geomean(ratios)
        out.append(f"- best exact kernel vs Embree (rays/s, geometric mean over r): {v:.2f}x "
                   f"(target >= 2): **{'met' if v >= 2 else 'missed'}**")
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


def speedup_markdown(df, env=None, title="hftrace reproduce", counts=None) -> str:
    """The Markdown report of a sweep's rows ``df``: the machine (``env``), the paper's
    measure, one speedup table per workload and surface (geometric mean over datasets)
    and, with ``counts`` (kernel -> counts.csv row), the cost model."""
    lines = [f"# {title}: speedup over `dda`", ""]
    if env:
        lines += [f"Machine: {env.get('cpu')} ({env.get('cores')} cores, one used), Python "
                  f"{env.get('python')}, NumPy {env.get('numpy')}, commit "
                  f"`{env.get('git_commit')}`.", ""]
    datasets = list(dict.fromkeys(df["dataset"]))
    lines += [f"Datasets: {', '.join(datasets)}. Rays per group: "
              f"{', '.join(map(str, sorted(set(df['rays']))))}; repeats: "
              f"{', '.join(map(str, sorted(set(df['repeats']))))}. Speedup = median time of dda / "
              "median time of the algorithm on the same rays in the same process (docs/"
              "METHOD.md); tables aggregate datasets by the geometric mean.", ""]
    table = pivot(df, *PRIMARY)
    if not table.empty:
        lines += ["## The paper's measure: first hit on triangles, by mean run length", "",
                  _markdown(table, paper=True), ""]
        part = df[(df["workload"] == PRIMARY[0]) & (df["surface"] == PRIMARY[1]) &
                  (df["run_length"] == "random")]
        if not part.empty:
            by_ds = part.pivot_table(index="dataset", columns="algorithm", values="speedup", sort=False)
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
        t = pivot(df, workload, surface)
        label = workload if surface == "-" else f"{workload}, {surface}"
        lines += [f"## Workload: {label}", "", _markdown(t), ""]
    lines += cost_model(df, counts)
    agree = df[df["agree"] < 1.0]
    if not agree.empty:
        worst = agree.groupby("algorithm")["agree"].min()
        lines += ["## Agreement with the exact reference (lowest per algorithm)", "",
                  "| algorithm | lowest agreement |", "|---|---|"]
        lines += [f"| {a} | {100 * v:.2f} % |" for a, v in worst.items()]
        lines.append("")
    return "\n".join(lines)


def _style(name):
    """Line style by accuracy: exact solid, float dashed, approximate dotted, peer dash-dot."""
    import algos

    entry = algos.INTERSECTOR_REGISTRY.get(name)
    accuracy = entry.accuracy if entry else "exact"
    return {"exact": "-", "float64": "--", "float32": "--", "approximate": ":"}.get(accuracy, "-.")


def plot_speedup(df, path, workload="first_hit", surface="triangles"):
    """Speedup over dda against mean run length for one workload and surface, one line per
    algorithm (geometric mean over datasets), saved as a PNG at ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    part = df[(df["workload"] == workload) & (df["surface"] == surface)]
    part = part[np.isfinite([_r_value(r) for r in part["run_length"]])]
    fig, ax = plt.subplots(figsize=(9, 5.5), dpi=120)
    if part.empty:
        ax.text(0.5, 0.5, "no rows", ha="center")
    names = [n for n in dict.fromkeys(part["algorithm"]) if n != "dda"]
    colours = plt.get_cmap("tab20")(np.linspace(0, 1, max(len(names), 1), endpoint=False))
    for colour, name in zip(colours, names):
        rows = part[part["algorithm"] == name]
        g = rows.groupby("run_length")
        r = np.array(sorted(g.groups, key=_r_value), dtype=object)
        x = np.array([_r_value(v) for v in r])
        y = np.array([_geomean(g.get_group(v)["speedup"]) for v in r])
        lo = np.array([_geomean(g.get_group(v)["speedup_ci_low"]) for v in r])
        hi = np.array([_geomean(g.get_group(v)["speedup_ci_high"]) for v in r])
        style = _style(name)
        line, = ax.plot(x, y, marker="o", ms=3, label=name, color=colour, ls=style, lw=1.6)
        ax.fill_between(x, lo, hi, color=colour, alpha=0.10, linewidth=0)
    px = [k for k in PAPER if k != "random"]
    ax.plot(px, [PAPER[k] for k in px], "k*", ms=12, label="Henning & Stephenson 2004")
    ax.axhline(PAPER["random"], color="k", ls=":", lw=1)
    ax.text(1.02, PAPER["random"], " paper: 1.25x average", va="bottom", fontsize=8)
    ax.axhline(1.0, color="grey", lw=0.8)
    ax.set_xscale("log")
    ax.set_xlabel("mean run length r (log)")
    ax.set_ylabel("speedup over dda (median ratio, 95 % CI band)")
    ax.set_title(f"{workload} on {surface}: run length vs speedup "
                 "(solid exact, dashed float, dotted marching)")
    ax.legend(fontsize=7, ncol=2)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def plot_cost(df, path):
    """ns/ray against cells/ray: O(n) walkers climb with n, run walkers with n/r."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), dpi=120)
    for ax, (workload, surface) in zip(axes, (("visit", "-"), PRIMARY)):
        part = df[(df["workload"] == workload) & (df["surface"] == surface)]
        for name in dict.fromkeys(part["algorithm"]):
            rows = part[part["algorithm"] == name]
            ax.scatter(rows["cells_per_ray"], rows["ns_per_ray"], s=10, label=name)
        ax.set_xlabel("cells per ray")
        ax.set_ylabel("ns per ray")
        ax.set_title(workload if surface == "-" else f"{workload}, {surface}")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)


def cost_model(df, counts=None) -> list:
    """The cost model's table: ns per ray, cell and run (medians over the first-hit
    groups on triangles), with instructions and branches per cell from ``counts.csv``
    (:mod:`bench.counts`) where they were counted."""
    cost = df[(df["workload"] == PRIMARY[0]) & (df["surface"] == PRIMARY[1])]
    if cost.empty:
        return []
    c = cost.groupby("algorithm", sort=False)[["ns_per_ray", "ns_per_cell", "ns_per_run"]].median()
    counts = counts or {}
    lines = ["## Cost model (first hit, triangles; medians over groups)", ""]
    if counts:
        any_row = next(iter(counts.values()))
        lines += [f"Instructions and branches per cell: callgrind, {any_row['dataset']} "
                  f"{any_row['size']}^2, r = {any_row['r']}, {any_row['rays']} rays "
                  "(`hftrace profile KERNEL`; per cell of the `runs` walk up to its hit, "
                  "each ray's setup included).", ""]
    else:
        lines += ["No instruction counts here (valgrind was not available, or "
                  "`--no-counts`); `hftrace profile KERNEL` gives them.", ""]
    lines += ["| algorithm | ns/ray | ns/cell | ns/run | instr/cell | branches/cell |",
              "|---|---|---|---|---|---|"]
    for a, r in c.iterrows():
        k = counts.get(a, {})
        lines.append(f"| {a} | {r.ns_per_ray:.0f} | {r.ns_per_cell:.2f} | {r.ns_per_run:.2f} | "
                     f"{k.get('instructions_per_cell', '')} | {k.get('branches_per_cell', '')} |")
    lines.append("")
    return lines


def write_reports(csv_path, out_dir=None, title="hftrace reproduce") -> dict:
    """speedup.md, run_length_vs_speedup.png and ns_per_ray_vs_cells.png from a CSV."""
    out_dir = out_dir or os.path.dirname(os.path.abspath(csv_path))
    os.makedirs(out_dir, exist_ok=True)
    df = load(csv_path)
    env_path = os.path.join(os.path.dirname(os.path.abspath(csv_path)), "env.json")
    env = json.load(open(env_path)) if os.path.exists(env_path) else None
    paths = {"speedup": os.path.join(out_dir, "speedup.md"),
             "plot": os.path.join(out_dir, "run_length_vs_speedup.png"),
             "cost": os.path.join(out_dir, "ns_per_ray_vs_cells.png")}
    from .counts import read_counts

    counts = read_counts(os.path.join(os.path.dirname(os.path.abspath(csv_path)), "counts.csv"))
    with open(paths["speedup"], "w") as f:
        f.write(speedup_markdown(df, env, title, counts=counts))
    plot_speedup(df, paths["plot"])
    plot_cost(df, paths["cost"])
    return paths
