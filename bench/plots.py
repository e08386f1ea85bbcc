"""The pictures of a results.csv (``hftrace plot``, ``hftrace reproduce``): speedup over
``dda`` against mean run length, and ns per ray against cells per ray, drawn with
matplotlib (Agg) from the same rows and intervals as the tables of :mod:`bench.analysis`.
"""
from __future__ import annotations

import numpy as np

from .report import PAPER, PLOT_KERNELS, PRIMARY, _geomean, _r_value, paired_design


def _style(name):
    """Line style by accuracy: exact solid, float dashed, approximate dotted, peer
    dash-dot. A plugin is solid only when it registered ``exact=True``, else dashed; a
    kernel this process does not know (a plugin not loaded) is dashed too, since nothing
    here backs an exactness claim."""
    import algos

    entry = algos.INTERSECTOR_REGISTRY.get(name) or algos.TRAVERSAL_REGISTRY.get(name)
    if entry is None or entry.plugin is not None:
        return "-" if entry is not None and entry.plugin.exact else "--"
    accuracy = entry.accuracy if hasattr(entry, "accuracy") else \
        ("exact" if entry.exact else entry.precision)
    return {"exact": "-", "float64": "--", "float32": "--", "approximate": ":"}.get(accuracy, "-.")


def plot_kernels(names, all_kernels=False) -> list:
    """The kernels a plot shows: :data:`PLOT_KERNELS` and every plugin, or all of them."""
    import algos

    names = [n for n in names if n != "dda"]
    if all_kernels:
        return names
    plugins = {n for n, a in algos.INTERSECTOR_REGISTRY.items() if a.plugin is not None}
    plugins |= {n for n, t in algos.TRAVERSAL_REGISTRY.items() if t.plugin is not None}
    return [n for n in names if n in PLOT_KERNELS or n in plugins or n not in _builtin_names()]


def _builtin_names():
    import algos

    return {n for n, a in algos.INTERSECTOR_REGISTRY.items() if a.plugin is None} | \
        {n for n, t in algos.TRAVERSAL_REGISTRY.items() if t.plugin is None}


def _colours(n):
    import matplotlib.pyplot as plt

    cmap = plt.get_cmap("tab10" if n <= 10 else "tab20")
    return [cmap(k % cmap.N) for k in range(max(n, 1))]


def speedup_axis_label(df) -> str:
    """The y label of the run-length plot: what its speedups are, by the rows' design."""
    how = "median of adjacent pairs' ratios" if paired_design(df) else \
        "geometric mean of paired ratios"
    return f"speedup over dda ({how})"


def plot_speedup(df, path, workload="first_hit", surface="triangles", all_kernels=False):
    """Speedup over dda against mean run length for one workload and surface, one line per
    algorithm (geometric mean over datasets), saved as a PNG at ``path``. By default the
    kernels of :data:`PLOT_KERNELS` and every plugin (``all_kernels`` for all); the 95 %
    interval of every kernel shown is drawn as a light band and as error bars set slightly
    apart along the run-length axis, so overlapping intervals stay apart; the legends stand
    right of the axes, off the data."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    part = df[(df["workload"] == workload) & (df["surface"] == surface)]
    part = part[np.isfinite([_r_value(r) for r in part["run_length"]])]
    fig, ax = plt.subplots(figsize=(10.5, 5.5), dpi=120, layout="constrained")
    if part.empty:
        ax.text(0.5, 0.5, "no rows", ha="center", transform=ax.transAxes)
    names = plot_kernels(dict.fromkeys(part["algorithm"]), all_kernels)
    for k, (colour, name) in enumerate(zip(_colours(len(names)), names)):
        rows = part[(part["algorithm"] == name) & np.isfinite(part["speedup"].astype(float))]
        if rows.empty:
            continue
        g = rows.groupby("run_length")
        r = np.array(sorted(g.groups, key=_r_value), dtype=object)
        x = np.array([_r_value(v) for v in r])
        y = np.array([_geomean(g.get_group(v)["speedup"]) for v in r])
        lo = np.array([_geomean(g.get_group(v)["speedup_ci_low"]) for v in r])
        hi = np.array([_geomean(g.get_group(v)["speedup_ci_high"]) for v in r])
        ax.plot(x, y, marker="o", ms=3, label=name, color=colour, ls=_style(name), lw=1.6)
        ax.fill_between(x, lo, hi, color=colour, alpha=0.10, linewidth=0)
        dodge = x * 1.025 ** (k - (len(names) - 1) / 2)  # apart on the log axis
        ax.errorbar(dodge, y, yerr=[np.maximum(y - lo, 0), np.maximum(hi - y, 0)], fmt="none",
                    ecolor=colour, elinewidth=1.2, capsize=2.5)
    drawn = {line.get_linestyle() for line in ax.get_lines()}  # the kernels' styles
    px = [k for k in PAPER if k != "random"]
    ax.plot(px, [PAPER[k] for k in px], "k*", ms=12, ls="none",
            label="Henning & Stephenson 2004, by r")
    ax.axhline(PAPER["random"], color="k", ls=(0, (1, 3)), lw=1,
               label=f"Henning & Stephenson 2004,\nall orientations ({PAPER['random']:g}x)")
    ax.axhline(1.0, color="grey", lw=0.8, label="dda, the baseline (1.0)")
    ax.set_xscale("log")
    ax.set_xlabel("mean run length r (log)")
    ax.set_ylabel(speedup_axis_label(df))  # the headline preset's were medians, labelled means
    where = workload if surface == "-" else f"{workload} on {surface}"
    ax.set_title(f"{where}: run length vs speedup\n(bars and bands: 95 % intervals)", fontsize=10)
    # the lines' legend right of the axes, off the data, and the key of their styles below it
    fig.legend(loc="outside right upper", fontsize=8, ncol=1 if len(names) <= 12 else 2)
    key = [matplotlib.lines.Line2D([], [], color="dimgrey", ls=style, lw=1.6, label=words)
           for style, words in (("-", "exact"), ("--", "float, or not claimed exact"),
                                (":", "approximate (marching)"), ("-.", "peer (Embree, float32)"))
           if style in drawn]
    if key:
        fig.legend(handles=key, title="line style", loc="outside right lower", fontsize=8,
                   title_fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.savefig(path)
    plt.close(fig)


def cost_panels(df) -> list:
    """The (workload, surface) panels of :func:`plot_cost`: a 2D workload (``visit`` where
    measured) and a first hit (the paper's measure where measured), each only when the
    rows hold one; the paper's measure alone for rows holding neither."""
    pairs = list(dict.fromkeys(zip(df["workload"], df["surface"])))
    two_d = [p for p in pairs if p[1] == "-"]
    hits = [p for p in pairs if p[1] != "-"]
    panels = [("visit", "-") if ("visit", "-") in pairs else (two_d[0] if two_d else None),
              PRIMARY if PRIMARY in pairs else (hits[0] if hits else None)]
    return [p for p in panels if p] or [PRIMARY]


def plot_cost(df, path, all_kernels=False):
    """ns/ray against cells/ray: O(n) walkers climb with n, run walkers with n/r. The same
    kernels as :func:`plot_speedup` (and ``dda``), one colour each, a legend per panel;
    one panel per workload of :func:`cost_panels` (a sweep of first hits on bilinear
    cells drew two empty panels, "visit" and "first_hit, triangles"). Returns them."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = cost_panels(df)
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.5), dpi=120,
                             squeeze=False)
    for ax, (workload, surface) in zip(axes[0], panels):
        part = df[(df["workload"] == workload) & (df["surface"] == surface)]
        names = ["dda"] + plot_kernels(dict.fromkeys(part["algorithm"]), all_kernels)
        names = [n for n in names if n in set(part["algorithm"])]
        for colour, name in zip(_colours(len(names)), names):
            rows = part[part["algorithm"] == name]
            ax.scatter(rows["cells_per_ray"], rows["ns_per_ray"], s=12, label=name,
                       color=colour, marker="os^Dv<>p*h"[names.index(name) % 10])
        ax.set_xlabel("cells per ray")
        ax.set_ylabel("ns per ray")
        ax.set_title(workload if surface == "-" else f"{workload}, {surface}")
        ax.grid(True, alpha=0.3)
        if names:
            ax.legend(fontsize=7)
        else:
            ax.text(0.5, 0.5, "no rows", ha="center", transform=ax.transAxes)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return panels
