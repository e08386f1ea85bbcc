"""``make fuzz``: coverage-guided fuzzing of the C entry points.

Each input is a byte string that :func:`decode` turns into one call of the public API,
``algos.traverse``, ``algos.intersect``, (first byte >= 240) ``algos.horizon`` or
``algos.viewshed``, or (first byte 0xFE) a rasteriser (``algos.raster.fuzz_one``:
``zbuffer``, ``painter``, ``floating_horizon``, ``watkins``, ``warnock`` or the hidden
lines, with arbitrary cameras and fields),
with arbitrary doubles (NaN, +-inf, +-0, subnormals, huge values, values on and next to
grid lines; a quarter of the first-hit cases rounded onto the integer lattice), grid
shapes up to and just past the documented limits, tmin/tmax, every
output mode and option. :func:`check` runs it and asserts the invariants:

* the call returns, or raises ValueError/TypeError (errors come back as errors); any other
  exception, a crash or a sanitizer report is a finding;
* the inputs are unmodified;
* every exact kernel equals every other exact kernel (traversal: ``midpoint`` and
  ``runs``; first hits: ``midpoint``, ``runs``, ``runs_periodic`` and ``runs_maxmip``);
* cells are 8-adjacent, never repeat and lie in the grid; runs are consistent with them;
* hits lie inside ``[tmin, tmax]`` and their cells in the grid;
* ``packet_maxmip`` equals ``dda_maxmip`` bit for bit (t, cell, normal, statistics) at
  every packet width, on every ``dda_maxmip`` input;
* horizon angles lie in [-pi/2, pi/2] and every exact horizon method agrees within 1e-9
  (the registry's: the C entries ``horizon_rows`` and ``horizon_chain`` included, through
  ``rows`` and ``chain``), with and without curvature; the viewshed's plain and mipmap
  walks agree bit for bit; in its other modes (every ``algos.terrain.VIEWSHED_MODES``: the
  C threshold walk and the angle) they agree to rounding, heights are >= 0 and angles in
  [-pi/2, pi/2].
* ``dda_compact`` gives ``dda_maxmip``'s hits bit for bit (tests/fuzz/compact_cases.py).
* ``plane_maxmip`` gives ``dda_maxmip``'s t, cell and normal bit for bit, on the case's
  rays and on vertical planes grown from them (tests/fuzz/plane_cases.py).
* ``pitched_maxmip`` gives them too, on the case's rays and on the batch of one eye made
  from them (tests/fuzz/pitched_cases.py).
* ``ring_maxmip`` gives them too (statistics included), on the case's rays and on a
  longer shuffled batch of them that refills and drains the ring (tests/fuzz/ring_cases.py).
* the chain walk's strips (``horizon_strips_frame``, ``horizon_strips``) of every horizon
  case bound the surface on its rays, level by level (tests/fuzz/strips_cases.py).

The decoder needs no fuzzer, so ``tests/fuzz/test_fuzz.py`` replays the committed corpus
(``tests/data/fuzz_corpus``; every finding is added there) in every test run.

    python -m tests.fuzz.harness [--seconds 60] [--runs N] [--crashes DIR] [CORPUS_DIR ...]

The first corpus directory receives the new inputs the fuzzer keeps; ``make fuzz`` works
on a copy of the committed corpus and runs the sanitized build.
"""
from __future__ import annotations

import math
import os
import struct
import sys

import numpy as np

import algos

from .compact_cases import check_compact
from .cone_cases import check_cone
from .pitched_cases import check_pitched
from .plane_cases import check_plane
from .ring_cases import check_ring
from .strips_cases import check_strips

TRAVERSALS = tuple(algos.TRAVERSAL_REGISTRY)
# (packet_maxmip, plane_maxmip, pitched_maxmip and ring_maxmip are not drawn on their own,
# which would remap the committed corpus: every dda_maxmip call is repeated with them and
# must match bit for bit)
INTERSECTORS = tuple(n for n, a in algos.INTERSECTOR_REGISTRY.items()
                     if a.kind != "peer"
                     and n not in ("packet_maxmip", "plane_maxmip", "pitched_maxmip", "ring_maxmip"))
PACKET_WIDTHS = (1, 2, 4, 8)
EXACT_TRAVERSALS = ("midpoint", "runs")
EXACT_INTERSECTORS = ("midpoint", "runs", "runs_periodic", "runs_maxmip")
CORPUS = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data",
                      "fuzz_corpus")

_SPECIAL = (0.0, -0.0, 1.0, -1.0, 0.5, -0.5, 2.0, 3.0, 1e-300, 5e-324, -5e-324, 2.0 ** 30,
            -(2.0 ** 30), 2.0 ** 30 + 1, 2.0 ** 31, 1e308, -1e308, 2.0 ** 1000, 2.0 ** 1001,
            math.nan, math.inf, -math.inf, 1 / 3, 0.1, 1 - 2 ** -53, 1 + 2 ** -52,
            65536.0, 2.0 ** -16, 0.75 / 65536)


class Reader:
    """Values from a byte string; past its end every value is 0."""

    def __init__(self, data: bytes):
        self.data, self.pos = data, 0

    def take(self, n: int) -> bytes:
        chunk = self.data[self.pos:self.pos + n]
        self.pos += n
        return chunk + b"\0" * (n - len(chunk))

    def byte(self) -> int:
        return self.take(1)[0]

    def u16(self) -> int:
        return struct.unpack("<H", self.take(2))[0]

    def small(self, scale=4.0) -> float:
        """A finite value on a 1/256 grid (a sane height)."""
        return (self.byte() - 128) / 256.0 * scale + (self.byte() % 8) * scale / 8

    def double(self, scale=8.0) -> float:
        """Mostly small values and values on or next to grid lines; sometimes a special
        value or raw bits."""
        kind = self.byte() % 8
        if kind <= 2:
            return (self.u16() - 32768) / 4096.0 * scale            # small, 1/4096 steps
        if kind == 3:
            v = float((self.u16() % 64) - 16)                         # on a grid line
            return float(np.nextafter(v, v + (1 if self.byte() % 2 else -1)))
        if kind == 4:
            return float((self.u16() % 80) - 16)
        if kind == 5:
            return _SPECIAL[self.byte() % len(_SPECIAL)]
        if kind == 6:
            return struct.unpack("<d", self.take(8))[0]               # any bits
        return (self.u16() - 32768) / 64.0


def decode(data: bytes) -> dict:
    """The call a byte string stands for."""
    r = Reader(data)
    first = r.byte()
    if first >= 240:
        return _decode_terrain(r, "viewshed" if first % 2 else "horizon")
    op = "intersect" if first % 2 else "traverse"
    n = r.byte() % 7
    case: dict = {"op": op}
    if r.byte() % 8 == 0:
        case["tmin"], case["tmax"] = r.double(), r.double()
    elif r.byte() % 8 == 0:
        case["tmin"] = [r.double() for _ in range(n)]
        case["tmax"] = [r.double() for _ in range(n)]
    if op == "traverse":
        big = r.byte() % 16
        if big == 0:
            shape = (2 ** 24 + r.byte() % 2, 1 + r.byte() % 8)        # at and past the limit
        elif big == 1:
            shape = (1 + r.u16() % 4096, 1 + r.u16() % 4096)
        else:
            shape = (1 + r.byte() % 40, 1 + r.byte() % 40)
        case.update(kernel=TRAVERSALS[r.byte() % len(TRAVERSALS)], shape=shape,
                    output=("cells", "runs", "count")[r.byte() % 3],
                    origins=[[r.double(30), r.double(30)] for _ in range(n)],
                    directions=[[r.double(), r.double()] for _ in range(n)])
        if shape[0] * shape[1] > 4096 * 4096 // 4:
            case["output"] = "count"
        if case["kernel"] == "runs_periodic" and r.byte() % 2:
            case["max_denominator"] = (1, 2, 7, 64, 2 ** 16, 2 ** 20, 0, -3)[r.byte() % 8]
    else:
        rows, cols = 1 + r.byte() % 24, 1 + r.byte() % 24
        wild = r.byte() % 8 == 0  # then any sample may be NaN, inf, huge or subnormal
        heights = [r.double(4.0) if wild else r.small() for _ in range(rows * cols)]
        case.update(kernel=INTERSECTORS[r.byte() % len(INTERSECTORS)],
                    surface=algos.SURFACES[r.byte() % len(algos.SURFACES)],
                    heights=np.asarray(heights, dtype=np.float64).reshape(rows, cols),
                    origins=[[r.double(20), r.double(20), r.double(6)] for _ in range(n)],
                    directions=[[r.double(), r.double(), r.double()] for _ in range(n)],
                    outputs=tuple(o for k, o in enumerate(("t", "cell", "normal", "stats"))
                                  if (r.byte() >> k) & 1) or ("t",))
        if r.byte() % 4 == 0:
            case["cull_cells"] = bool(r.byte() % 2)
        if r.byte() % 4 == 1:
            # on the lattice: integer heights and rays, which touch the surface at
            # parameters that are not floats (1/3 ...): the cell tests' exact cold path
            # (cext/surfaces/exact_cell.h) and the dropped side cells of the float walks
            with np.errstate(invalid="ignore"):
                case["heights"] = np.round(case["heights"] * 2)
                case["origins"] = np.round(np.asarray(case["origins"], float)).tolist()
                case["directions"] = np.round(np.asarray(case["directions"], float)).tolist()
    return case


HORIZON_EXACT = tuple(n for n, a in algos.HORIZON_ALGORITHMS.items() if a.exact)
VIEWSHED_MODES = algos.terrain.VIEWSHED_MODES


def _decode_terrain(r: Reader, op: str) -> dict:
    rows, cols = 1 + r.byte() % 14, 1 + r.byte() % 14
    wild = r.byte() % 8 == 0
    heights = [r.double(4.0) if wild else r.small() for _ in range(rows * cols)]
    case = {"op": op, "heights": np.asarray(heights, dtype=np.float64).reshape(rows, cols)}
    if r.byte() % 4 == 0:
        case["max_distance"] = r.double(6.0)
    if op == "horizon":
        kind = r.byte() % 4
        case["azimuth"] = (float(r.byte() % 8 * 45) if kind == 0 else
                           float(r.byte() * 360.0 / 256) if kind == 1 else r.double(400.0))
        case["kernel"] = HORIZON_EXACT[r.byte() % len(HORIZON_EXACT)]
        # curvature (the kernels' kappa): last, and off past the end of the input, so the
        # committed corpus decodes as before; a tiny earth radius (cells) makes it strong
        if r.byte() % 4 == 3:
            case["earth_radius"] = r.double(40.0)
    else:
        case["observer"] = [r.double(16.0), r.double(16.0)]
        case["observer_height"] = r.double(2.0) if r.byte() % 4 == 0 else abs(r.small())
        case["kernel"] = tuple(algos.VIEWSHED_ALGORITHMS)[r.byte() % 2]
        # past the end of the input the mode is "normal": older corpus entries keep their call
        case["mode"] = VIEWSHED_MODES[r.byte() % len(VIEWSHED_MODES)]
    return case


def _call_terrain(case, kernel):
    md = case.get("max_distance")
    if case["op"] == "horizon":
        curve = {} if "earth_radius" not in case else dict(
            curvature=True, spacing=1.0, earth_radius=case["earth_radius"])
        return algos.horizon(case["heights"], case["azimuth"], md, algorithm=kernel, **curve)
    mode = case.get("mode", "normal")
    # (mode "observer" computes the observer height: the decoded one is left out)
    return algos.viewshed(case["heights"], case["observer"],
                          None if mode == "observer" else case["observer_height"],
                          max_distance=md, algorithm=kernel, mode=mode)


def _check_terrain(case, result):
    if case["op"] == "horizon":
        assert result.shape == (1,) + case["heights"].shape
        # NaN exactly at the void vertices (algos.horizon's contract), an angle elsewhere
        voids = np.isnan(case["heights"])[None]
        assert np.array_equal(np.isnan(result), voids), "NaN where no void is, or none at a void"
        angles = result[~voids]
        assert np.all((angles >= -math.pi / 2) & (angles <= math.pi / 2)), "an angle out of range"
        for other in HORIZON_EXACT:
            try:
                got = _call_terrain(case, other)
            except ValueError:  # the sweep needs a rational azimuth, no max_distance and
                continue        # no curvature
            assert np.allclose(got, result, rtol=0, atol=1e-9, equal_nan=True), \
                f"{case['kernel']} and {other} differ"
        return
    mode = case.get("mode", "normal")
    if mode != "normal":
        # the thresholds (hf_viewshed_threshold) and angles: float64, NaN only at voids and
        # out of range; the plain and mipmap walks agree to rounding
        assert result.dtype == np.float64 and result.shape == case["heights"].shape
        if mode == "angle":
            ok = np.isnan(result) | ((result >= -math.pi / 2) & (result <= math.pi / 2))
            assert ok.all(), "an angle out of range"
        else:
            assert np.all(np.isnan(result) | (result >= 0) | (mode == "dem")), "a negative height"
        scale = 1.0 + float(np.nanmax(np.abs(case["heights"]))) + abs(case["observer_height"])
        for other in algos.VIEWSHED_ALGORITHMS:
            got = _call_terrain(case, other)
            assert np.allclose(got, result, rtol=1e-7, atol=1e-7 * scale, equal_nan=True), \
                f"{case['kernel']} and {other} differ in mode {mode}"
        return
    assert result.dtype == bool and result.shape == case["heights"].shape
    for other in algos.VIEWSHED_ALGORITHMS:
        assert np.array_equal(_call_terrain(case, other), result), \
            f"{case['kernel']} and {other} differ"


def _frozen(case):
    return {k: np.array(v, dtype=object if isinstance(v, str) else None, copy=True)
            if isinstance(v, (list, np.ndarray)) else v for k, v in case.items()}


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    if a.dtype.kind == "f" and b.dtype.kind == "f":
        return a.shape == b.shape and bool(np.all((a == b) | (np.isnan(a) & np.isnan(b))))
    return bool(np.array_equal(a, b))


def _call(case, kernel=None):
    kernel = kernel or case["kernel"]
    if case["op"] in ("horizon", "viewshed"):
        return _call_terrain(case, kernel)
    if case["op"] == "traverse":
        kw = {"output": case["output"]}
        if "max_denominator" in case and kernel == "runs_periodic":
            kw["max_denominator"] = case["max_denominator"]
        return algos.traverse(kernel, np.asarray(case["origins"], dtype=float).reshape(-1, 2),
                              np.asarray(case["directions"], dtype=float).reshape(-1, 2),
                              case["shape"], case.get("tmin"), case.get("tmax"), **kw)
    kw = {}
    if "cull_cells" in case:
        kw["cull_cells"] = case["cull_cells"]
    if "packet_width" in case and kernel == "packet_maxmip":
        kw["packet_width"] = case["packet_width"]
    return algos.intersect(kernel, case["heights"],
                           np.asarray(case["origins"], dtype=float).reshape(-1, 3),
                           np.asarray(case["directions"], dtype=float).reshape(-1, 3),
                           surface=case["surface"], tmin=case.get("tmin"), tmax=case.get("tmax"),
                           outputs=case["outputs"], **kw)


def _check_cells(paths, shape):
    nx, ny = shape
    for k in range(len(paths.offsets) - 1):
        cells = paths.cells[paths.offsets[k]:paths.offsets[k + 1]]
        if len(cells) == 0:
            continue
        assert cells[:, 0].min() >= 0 and cells[:, 0].max() < nx, "a cell outside the grid"
        assert cells[:, 1].min() >= 0 and cells[:, 1].max() < ny, "a cell outside the grid"
        step = np.abs(np.diff(cells.astype(np.int64), axis=0))
        assert np.all(step.max(axis=1, initial=0) == 1) if len(step) else True, \
            f"ray {k}: consecutive cells are not adjacent"
        keys = cells[:, 0].astype(np.int64) * (ny + 1) + cells[:, 1]
        assert len(np.unique(keys)) == len(keys), f"ray {k}: a cell repeats"


def check(data: bytes) -> None:
    """Run one decoded call and assert the invariants (module docstring)."""
    with np.errstate(all="ignore"):
        _check(data)


def _check(data: bytes) -> None:
    if data[:1] == b"\xfe":  # the rasterisers' branch (algos.raster.fuzz_one)
        import algos.raster

        algos.raster.fuzz_one(data[1:])
        return
    case = decode(data)
    before = _frozen(case)
    try:
        result = _call(case)
    except (ValueError, TypeError):
        result = None
    for k, v in before.items():
        if isinstance(v, np.ndarray):
            assert _same(v, np.asarray(case[k], dtype=v.dtype)), f"the call modified {k}"
    if result is None:
        return
    if case["op"] in ("horizon", "viewshed"):
        _check_terrain(case, result)
        check_strips(case)  # the chain walk's strips bound the surface (strips_cases.py)
        return
    if case["op"] == "traverse":
        if case["output"] == "cells":
            _check_cells(result, case["shape"])
        if case["kernel"] in EXACT_TRAVERSALS:
            other = _call(case, "runs" if case["kernel"] == "midpoint" else "midpoint")
            for field in ("cells", "runs", "offsets", "counts"):
                if hasattr(result, field):
                    assert _same(getattr(result, field), getattr(other, field)), \
                        f"{case['kernel']} and the other exact traversal differ in {field}"
        return
    t = getattr(result, "t", None)
    n = len(case["origins"])
    if t is not None:
        lo = np.broadcast_to(np.asarray(case.get("tmin", 0.0), dtype=float), (n,))
        hi = np.broadcast_to(np.asarray(case.get("tmax", math.inf), dtype=float), (n,))
        hit = np.isfinite(t)
        assert np.all((t[hit] >= lo[hit]) & (t[hit] <= hi[hit])), "a hit outside [tmin, tmax]"
        assert np.all(np.isinf(t[~hit]) & (t[~hit] > 0)), "a miss that is not +inf"
    cell = getattr(result, "cell", None)
    if cell is not None:
        rows, cols = case["heights"].shape
        found = cell[:, 0] >= 0
        assert np.all((cell[found, 0] < cols - 1) & (cell[found, 1] >= 0) & (cell[found, 1] < rows - 1))
        if t is not None:
            assert np.array_equal(found, np.isfinite(t)), "cell and t disagree on a hit"
    if case["kernel"] in EXACT_INTERSECTORS and t is not None:
        for other in EXACT_INTERSECTORS:
            if other != case["kernel"]:
                got = _call(case, other)
                assert _same(got.t, t), f"{case['kernel']} and {other} differ: {t} {got.t}"
    check_cone(case, _call)  # the cone kernel gives dda's hits (tests/fuzz/cone_cases.py)
    if case["kernel"] == "dda_maxmip":
        _check_packets(case, result)
    check_compact(case, _call)  # dda_compact gives dda_maxmip's (tests/fuzz/compact_cases.py)
    check_plane(case, _call)  # so does plane_maxmip, on planes too (tests/fuzz/plane_cases.py)
    check_pitched(case, _call)  # and pitched_maxmip, from one eye too (pitched_cases.py)
    check_ring(case, _call)  # and ring_maxmip, on a long batch too (ring_cases.py)


def _check_packets(case, result):
    """packet_maxmip equals dda_maxmip bit for bit (every output asked for) at every width."""
    for width in PACKET_WIDTHS:
        got = _call(dict(case, packet_width=width), "packet_maxmip")
        for name in ("t", "cell", "normal"):
            a, b = getattr(result, name), getattr(got, name)
            if a is not None:
                assert np.array_equal(np.asarray(a).view(np.uint8), np.asarray(b).view(np.uint8)), \
                    f"packet_maxmip (width {width}) and dda_maxmip differ in {name}: {b} {a}"
        if result.stats is not None:
            for k, v in result.stats.items():
                assert np.array_equal(v, got.stats[k]), \
                    f"packet_maxmip (width {width}) and dda_maxmip differ in {k}"


def main(argv=None):
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("corpus", nargs="*", default=[CORPUS])
    parser.add_argument("--seconds", type=int, default=60)
    parser.add_argument("--runs", type=int, default=-1, help="executions (-1: until --seconds)")
    parser.add_argument("--crashes", default=os.path.join(CORPUS, "crashes"),
                        help="where a finding is written (commit it: the tests replay it)")
    args = parser.parse_args(argv)
    try:
        import atheris
    except ImportError:
        sys.exit("fuzz: atheris is not installed (pip install -e '.[fuzz]'; `make fuzz` does it)")
    crashes = args.crashes
    os.makedirs(crashes, exist_ok=True)
    # coverage of the Python side (decoding, validation, dispatch) guides the search, and
    # under `make fuzz` the C extension's own libFuzzer counters (clang's fuzzer-no-link)
    atheris.instrument_all()
    fuzzer_args = [sys.argv[0], f"-max_total_time={args.seconds}", f"-runs={args.runs}",
                   f"-artifact_prefix={crashes}{os.sep}", "-max_len=4096", "-print_final_stats=1",
                   *args.corpus]
    atheris.Setup(fuzzer_args, check)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
