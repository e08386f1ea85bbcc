"""One row of ``hftrace targets`` (:mod:`bench.studies.targets`), measured in a process
of its own: ``python -m bench.studies.targets_measure --child SPEC``.

A ray row times every strict intersector of the registry and every Embree configuration
reached, side by side, interleaved, in both cache regimes (:func:`measure_rays`); the
horizon row times the 16 equal azimuths (:func:`measure_horizon`). ``--count-child SPEC``
is the process :mod:`bench.studies.targets_counts` runs under callgrind. The spec is the
JSON of the row's kind, field side, tier configuration and seed, so a tier defined by a
caller (the tests' tiny one) reaches the child.
"""
from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

__all__ = ["PEERS", "SCREEN", "PITCH", "REFERENCE", "embree_configs", "peer_configs",
           "row_rays", "measure_rays", "measure_horizon", "counted_rays", "save_case", "main"]

#: The peers a ray row compares against: embreex and the C Embree 3 peer.
PEERS = ("embreex", "embree3")
#: A strict kernel whose screening call (one warm call) is this many times slower than
#: the fastest one's is left out of the interleaved timing: it cannot be the best.
SCREEN = 3.0
#: Pitch of the pinhole camera of line 4, degrees below the horizontal.
PITCH = 2.6
#: The exact reference the kernels' hits are checked against.
REFERENCE = "runs"

# ---- one row, in its own process -----------------------------------------------------------

def _strict_names(kernels=None, surface="triangles"):
    """The registry's strict intersectors (accuracy exact or float64; no peer, no plugin)
    on ``surface``; with ``kernels``, those of its names (an unknown name is left out)."""
    import algos

    names = [n for n, a in algos.INTERSECTOR_REGISTRY.items()
             if a.kind not in ("peer", "plugin") and a.accuracy in ("exact", "float64")
             and surface in a.surfaces]
    return names if kernels is None else [n for n in kernels if n in names]


def embree_configs(coherent: bool):
    """(label, prepare(field, o, d) -> (run, t), is_mesh) of every Embree configuration
    this machine reaches: :func:`peer_configs` without the peer's name."""
    return [(label, prepare, is_mesh) for _, label, prepare, is_mesh in peer_configs(coherent)]


def peer_configs(coherent: bool, peers=PEERS):
    """(peer, label, prepare(field, o, d) -> (run, t), is_mesh) of every Embree
    configuration this machine reaches among ``peers``: embreex (single rays, triangles)
    and the C peer's geometries and native packet widths, coherent flag for width > 1
    when ``coherent``. A peer that is not installed yields nothing."""
    out = []
    if "embreex" in peers:
        try:
            import embreex  # noqa: F401

            from algos.peers.embree import embree_timed
        except ImportError:
            pass
        else:
            out.append(("embreex", "embreex triangles x1",
                        lambda f, o, d: embree_timed(f, o, d, threads=1), True))
    if "embree3" in peers:
        from algos.peers import embree3 as embree3_peer

        if embree3_peer.available():
            for geometry in ("grid", "triangles"):
                for width in embree3_peer.native_widths():
                    flag = " coherent" if coherent and width > 1 else ""
                    out.append(("embree3", f"embree3 {geometry} x{width}{flag}",
                                lambda f, o, d, g=geometry, w=width: embree3_peer.embree3_timed(
                                    f, o, d, geometry=g, packet=w,
                                    coherent=coherent and w > 1, threads=1),
                                geometry == "triangles"))
    return out


def _peer_missing(peer) -> str:
    """Why ``peer`` has no configuration here."""
    if peer == "embreex":
        return "not available (embreex does not import: pip install embreex)"
    if peer != "embree3":
        return f"not available (no peer named {peer!r})"
    from algos.peers import embree3 as embree3_peer

    return f"not available ({embree3_peer.unavailable_reason() or 'no native packet width'})"


def row_rays(kind, side, cfg, seed):
    """(field, origins, directions, coherent, setting) of a ray row: ``random`` rays
    (``first_hit_rays``, azimuths uniform, 5-20 degrees down) on fBm ``side``^2 (seed 1),
    or the ``level`` and ``pitched`` cameras of :mod:`bench.studies.plane_counts` and
    :mod:`bench.studies.pitched_counts` at the tier's image size."""
    import algos
    import datasets_gen

    width, height = cfg["image"]
    if kind == "random":
        from datasets_gen.rays import first_hit_rays

        field = algos.Field(datasets_gen.load("fbm", size=side, seed=1).heights)
        o, d = first_hit_rays(field, "random", cfg["rays"], seed)
        return field, o, d, False, f"fBm {side}^2, {len(o)} random rays"
    if kind == "level":
        from .plane_counts import camera_rays

        field, o, d = camera_rays(side, width, height)
        return field, o, d, True, f"fBm {side}^2, level camera {width}x{height}, 60 deg"
    if kind == "pitched":
        from .pitched_counts import camera_rays

        field, o, d = camera_rays(side, width, height, PITCH)
        return field, o, d, True, (f"fBm {side}^2, pinhole {width}x{height}, 60 deg, "
                                   f"{PITCH} deg down")
    raise ValueError(f"kind: expected random, level or pitched, got {kind!r}")


#: The cache state of a confirmation's paired rounds for each regime of
#: ``bench.timing.REGIMES`` (``bench.timing.FLUSH_MODES``): flushed before every timed
#: call, or warm (an untimed call, then timed calls).
CONFIRM_FLUSH = {"flushed": "call", "warm": "warm"}


def _prepare_alone(peer, label, prepare, field, o, d):
    """A peer configuration timed apart (its triangle mesh too large to keep beside the
    others): its job and output on a Field of its own, after one untimed call."""
    import algos

    own = algos.Field(field.heights)
    job, out = prepare(own, o, d)
    job()
    return job, out, own


def confirm(peer_job, label, our_job, best, n, regime, cfg, seed) -> dict:
    """The ratio of a selected peer configuration to our selected kernel, measured afresh
    in paired rounds with the peer as baseline (``bench.timing.paired_rounds``, until the
    interval is ``cfg["precision"]`` wide on either side or ``cfg["confirm_budget_s"]`` is
    spent) and read as the median pair with its distribution-free interval
    (``bench.timing.median_ratio_interval``). Returns ``config``, ``ns`` (the peer's
    median ns per ray), ``ours_ns``, ``ratio``, ``low``, ``high``, ``pairs`` and ``stop``
    (``bench.timing.STOPS``)."""
    from ..timing import WARM_TIMED_CALLS, median_ratio_interval, paired_rounds

    flush = CONFIRM_FLUSH[regime]
    m = paired_rounds({label: peer_job, best: our_job}, label,
                      precision=cfg.get("precision", 0.02),
                      budget_s=cfg.get("confirm_budget_s", 10.0), min_rounds=8,
                      flush=flush, seed=seed)
    calls = WARM_TIMED_CALLS if flush == "warm" else 1
    ratio, low, high = median_ratio_interval(m.log_ratios[best])
    return dict(config=label, ns=round(float(np.median(m.times[label])) / calls / n, 3),
                ours_ns=round(float(np.median(m.times[best])) / calls / n, 3), ratio=ratio,
                low=low, high=high, pairs=int(len(m.log_ratios[best])), stop=m.stop[best])


def measure_rays(kind, side, cfg, seed, echo=print) -> dict:
    """Time a ray row in this process (pinned to one CPU): every strict kernel and every
    Embree configuration, interleaved, in each regime. Returns a JSON-ready dict:
    ``setting``, ``rays``, ``agree`` (name -> fraction of rays agreeing with the exact
    reference), ``missing`` (peer -> why absent), and per regime the ns per ray of every
    contender, the best exact kernel, and per peer its fastest configuration with the
    ratio and interval (:func:`confirm`)."""
    import algos
    from algos.intersect import prepare_timed_intersect

    from ..sweep import hit_agreement
    from ..timing import REGIMES, pin_to_one_cpu, timed_in_regime

    cpu = pin_to_one_cpu()
    field, o, d, coherent, setting = row_rays(kind, side, cfg, seed)
    n = len(o)
    reference = algos.intersect(REFERENCE, field, o, d, threads=1).t
    ours, outs = {}, {}
    for name in _strict_names(cfg.get("kernels")):
        ours[name], outs[name] = prepare_timed_intersect(name, field, o, d)
        ours[name]()  # an output is the latest call's
    agree = {k: hit_agreement(outs[k](), reference, 1e-9) for k in ours}
    exact = [k for k in ours if agree[k] == 1.0]
    # screening: one warm call each; a kernel SCREEN times slower than the fastest cannot
    # be the best, and a per-cell walk on 230k grazing camera rays would take minutes
    screen = {k: ours[k]() / n for k in exact}
    fastest = min(screen.values(), default=math.inf)
    left_out = {k: round(v, 1) for k, v in screen.items() if v > SCREEN * fastest}
    exact = [k for k in exact if k not in left_out]
    for k in left_out:
        del ours[k]
    peers = cfg.get("peers") or PEERS
    configs = peer_configs(coherent, peers)
    present = {p for p, *_ in configs}
    result = dict(setting=setting, rays=n, side=side, cpu=cpu, agree=agree, left_out=left_out,
                  missing={p: _peer_missing(p) for p in peers if p not in present},
                  configs={label: peer for peer, label, _, _ in configs}, regimes={})
    big = max(field.heights.shape) > cfg["mesh_max_side"]
    jobs, alone = dict(ours), []
    for peer, label, prepare, is_mesh in configs:
        if is_mesh and big:
            alone.append((peer, label, prepare))
        else:
            jobs[label], outs[label] = prepare(field, o, d)
            jobs[label]()
            agree[label] = hit_agreement(outs[label](), reference, 1e-4)
    for regime in REGIMES:
        # selection: the interleaved repeats pick our best exact kernel and each peer's
        # fastest configuration; the ratio is then measured afresh (confirmation), so the
        # luck that made a contender look fastest does not enter its ratio
        times = timed_in_regime(jobs, cfg["repeats"], regime)
        ns = {k: float(np.median(v)) / n for k, v in times.items()}
        best = min(exact, key=ns.get) if exact else None
        for peer, label, prepare in alone if best is not None else ():
            # one peer's triangle mesh at a time, on a Field of its own (the C peer's
            # widths share its scene), freed before the next peer's
            job, out, own = _prepare_alone(peer, label, prepare, field, o, d)
            pair = timed_in_regime({best: jobs[best], label: job}, cfg["repeats"], regime)
            ns[label] = float(np.median(pair[label])) / n
            agree[label] = hit_agreement(out(), reference, 1e-4)
            del job, out, own
        entry = dict(ns={k: round(v, 3) for k, v in ns.items()}, best=best, peers={},
                     paired_apart=sorted(label for _, label, _ in alone))
        for peer in peers:
            labels = [lb for lb, p in result["configs"].items() if p == peer and lb in ns]
            if best is None or not labels:
                continue
            label = min(labels, key=ns.get)
            if label in jobs:
                entry["peers"][peer] = confirm(jobs[label], label, jobs[best], best, n, regime,
                                               cfg, seed)
            else:
                prepare = next(pr for pe, lb, pr in alone if lb == label)
                job, out, own = _prepare_alone(peer, label, prepare, field, o, d)
                entry["peers"][peer] = confirm(job, label, jobs[best], best, n, regime, cfg,
                                               seed)
                del job, out, own
        result["regimes"][regime] = entry
        echo(f"    {regime}: best {best}" + "".join(
            f"; {p} {v['config']} {v['ratio']:.2f}x [{v['low']:.2f}, {v['high']:.2f}] "
            f"({v['pairs']} pairs, {v['stop']})" for p, v in entry["peers"].items()))
    return result


def measure_horizon(side, cfg) -> dict:
    """Seconds of the horizon at the 16 equal azimuths of
    ``bench.studies.terrain_azimuths`` (Jacksboro ``side``, unlimited distance, one
    thread), in this process pinned to one CPU: one value per timed call."""
    import algos.terrain as T
    import datasets_gen

    from ..timing import pin_to_one_cpu
    from .terrain_azimuths import SIXTEEN, _timed

    cpu = pin_to_one_cpu()
    hf = datasets_gen.load("jacksboro", size=side)
    rows, cols = hf.heights.shape
    seconds = [_timed(lambda: T.horizon(hf, SIXTEEN, threads=1))[0]
               for _ in range(cfg["horizon_repeats"])]
    return dict(setting=f"Jacksboro {rows} x {cols}, 16 azimuths, unlimited distance, "
                        "1 thread", seconds=seconds, cpu=cpu)


def save_case(kind, side, cfg, seed, directory) -> int:
    """Write the row's heights and its :func:`counted_rays` to ``directory`` (``.npy``),
    built natively, so that the process under valgrind only loads them; the number of
    rays."""
    field, o, d, coherent, _ = row_rays(kind, side, cfg, seed)
    keep = counted_rays(kind, cfg)
    np.save(os.path.join(directory, "heights.npy"), field.heights)
    np.save(os.path.join(directory, "origins.npy"), o[keep])
    np.save(os.path.join(directory, "directions.npy"), d[keep])
    with open(os.path.join(directory, "case.json"), "w") as f:
        json.dump(dict(coherent=coherent), f)
    return len(keep)


def _count_child(spec) -> None:
    """The counted process: the case of :func:`save_case` loaded, the contender prepared;
    then a flush and two calls (the entries' dumps split them)."""
    import algos
    from algos.intersect import prepare_timed_intersect

    from ..timing import flush_caches

    def load(name):
        return np.load(os.path.join(spec["case"], f"{name}.npy"))

    with open(os.path.join(spec["case"], "case.json")) as f:
        coherent = json.load(f)["coherent"]
    field, o, d = algos.Field(load("heights")), load("origins"), load("directions")
    who = spec["contender"]
    if who in algos.INTERSECTOR_REGISTRY:
        run, _ = prepare_timed_intersect(who, field, o, d)
    else:
        run = next(prep for label, prep, _ in embree_configs(coherent) if label == who)(
            field, o, d)[0]
    flush_caches()
    run()  # flushed
    run()  # warm: right after its own call


def counted_rays(kind, cfg) -> np.ndarray:
    """Indices of the rays counted under callgrind: all of them when ``count_rays`` is
    None (a per-batch cost, such as the pitched kernel's coarse image, is then shared
    as in the timings), else about ``count_rays``: every k-th random ray, or every k-th
    image column whole (a column is one vertical plane of the level camera: a subsample
    across columns would leave its kernel no plane to share)."""
    n = cfg["rays"] if kind == "random" else cfg["image"][0] * cfg["image"][1]
    if cfg["count_rays"] is None or cfg["count_rays"] >= n:
        return np.arange(n)
    if kind == "random":
        return np.arange(0, n, max(1, n // cfg["count_rays"]))
    width, height = cfg["image"]
    columns = max(1, min(width, round(cfg["count_rays"] / height)))
    pixels = np.arange(width * height).reshape(height, width)
    return np.ascontiguousarray(pixels[:, np.arange(columns) * width // columns]).ravel()


def _child_env():
    """The environment of a child process: this tree first on PYTHONPATH, one BLAS
    thread, no preloaded sanitizer runtime."""
    root = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    env["PYTHONPATH"] = root + os.pathsep + env.get("PYTHONPATH", "")
    env.pop("LD_PRELOAD", None)  # a sanitizer runtime cannot run under valgrind
    return env


def _jsonable(value):
    """NumPy scalars as Python numbers, for ``json.dump``."""
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


# ---- the child processes' entry -------------------------------------------------------------

def main(argv=None) -> int:
    """The processes of :func:`bench.studies.targets.run`: ``--child SPEC`` measures one
    row and writes its JSON to ``SPEC["out"]``; ``--count-child SPEC`` is the process
    counted under callgrind."""
    parser = argparse.ArgumentParser(description="one row of the targets table (internal)")
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--child", default=None)
    group.add_argument("--count-child", default=None)
    args = parser.parse_args(argv)
    if args.count_child:
        _count_child(json.loads(args.count_child))
        return 0
    spec = json.loads(args.child)
    if spec["kind"] == "horizon":
        result = measure_horizon(spec["side"], spec["cfg"])
    else:
        result = measure_rays(spec["kind"], spec["side"], spec["cfg"], spec["seed"],
                              echo=lambda *_: None)
    with open(spec["out"], "w") as f:
        json.dump(result, f, default=_jsonable)
    return 0


if __name__ == "__main__":
    sys.exit(main())
