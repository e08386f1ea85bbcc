"""``hftrace reproduce``: the speedup-by-run-length study of Henning & Stephenson (2004),
measured here, next to every registered algorithm and Embree.

Presets (both seeded; every field is generated or loaded from the embedded data):

* quick (default, a few minutes at most here): fBm, terraces and uniform random at
  1024^2 and the Jacksboro DEM upsampled to 2048 samples on its longer side; r in
  {1, 2, 5, 25, 100} plus uniformly random azimuths; workloads visit, runs and first_hit
  on all four surfaces; 1000 rays per group, 7 interleaved repeats.
* full (``--full``): adds fBm 2048^2; r in {1, 1.5, 2, 3, 5, 8, 13, 25, 50, 100} plus
  random; 3000 rays, 9 repeats (about 330 groups: an estimated 20-30 minutes here).

Both presets end with the "parallel rays" part (``bench.studies.parallel_rays``):
every vertex's horizon along azimuths of slope 1/r, and orthographic first hits, on the
embedded Jacksboro DEM with every method and the peers: ``parallel.md``, ``parallel.csv``
and ``products.png``.
"""
from __future__ import annotations

import os

from .. import analysis
from ..sweep import SweepConfig, run_sweep
from ..timing import pin_to_one_cpu

#: The repository's root: ``publish`` writes its ``reports/``
REPOSITORY = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

DATASETS_QUICK = [
    {"name": "fbm", "size": 1024, "seed": 1},
    {"name": "terraces", "size": 1024, "seed": 1},
    {"name": "uniform", "size": 1024, "seed": 1},
    {"name": "jacksboro", "size": 2048},
]


def preset(full=False) -> SweepConfig:
    """The sweep of the quick preset, or with ``full`` the paper-scale one (module
    docstring)."""
    if full:
        return SweepConfig(
            name="reproduce-full", rays=3000, repeats=9, seed=2004,
            workloads=["visit", "runs", "first_hit"],
            surfaces=["flat", "plane3", "triangles", "bilinear"],
            run_lengths=[1, 1.5, 2, 3, 5, 8, 13, 25, 50, 100, "random"],
            datasets=DATASETS_QUICK + [{"name": "fbm", "size": 2048, "seed": 1}])
    return SweepConfig(
        name="reproduce", rays=1000, repeats=7, seed=2004,
        workloads=["visit", "runs", "first_hit"],
        surfaces=["flat", "plane3", "triangles", "bilinear"],
        run_lengths=[1, 2, 5, 25, 100, "random"], datasets=list(DATASETS_QUICK))


def run(full=False, out_dir=None, resume=False, progress=True, echo=print, counts=True,
        publish=False):
    """Run the study and write its reports; returns the paths of ``analysis.write_reports``.

    ``out_dir`` defaults to ``results/<preset>`` under the current directory (untracked);
    ``publish`` writes to the committed reference, ``reports/<preset>`` of the repository,
    instead. ``counts``: also the instruction counts (callgrind, when valgrind exists);
    ``resume``: keep the rows already measured."""
    cfg = preset(full)
    if publish and out_dir is not None:
        raise ValueError("out_dir: give either an output directory or publish, not both")
    if publish:
        out_dir = os.path.join(REPOSITORY, "reports", cfg.name)
    out_dir = out_dir or os.path.join("results", cfg.name)
    pin_to_one_cpu()
    run_sweep(cfg, out_dir, resume=resume, progress=progress, echo=echo)
    if counts:
        # the cost model's instruction counts (callgrind), next to the timings
        from ..counts import write_counts

        df = analysis.load(os.path.join(out_dir, "results.csv"))
        kernels = list(dict.fromkeys(df.loc[df["workload"] == "first_hit", "algorithm"]))
        write_counts(os.path.join(out_dir, "counts.csv"), kernels, resume=resume, echo=echo)
    # parallel rays at work: horizons and orthographic first hits at slopes 1/r, with
    # every method and the peers (bench/studies/parallel_rays.py)
    from .parallel_rays import run_parallel

    run_parallel(out_dir=out_dir, resume=resume, echo=echo,
                 repeats=7 if full else 5, sample=40000 if full else 20000)
    paths = analysis.write_reports(os.path.join(out_dir, "results.csv"), out_dir,
                                   title=f"hftrace reproduce ({'full' if full else 'quick'} preset)")
    with open(paths["speedup"]) as f:
        text = f.read()
    echo(text[: text.find("## Workload")] if "## Workload" in text else text)
    echo(f"wrote {out_dir}/results.csv, speedup.md, run_length_vs_speedup.png, "
         f"ns_per_ray_vs_cells.png, env.json")
    return paths
