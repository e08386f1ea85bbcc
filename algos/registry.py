"""The one registry of algorithms: name -> kernel, reference and properties.

Tests, benchmarks, the CLI and the reports iterate over :data:`TRAVERSAL_REGISTRY`; none
keeps a list of its own.
"""
from __future__ import annotations

from dataclasses import dataclass

from ._kernels import KERNEL_IDS as _C_ID  # the kernel ids, written once in C

# TRAVERSALS and INTERSECTORS are served by the module's __getattr__ (bottom)
__all__ = ["Traversal", "TRAVERSAL_REGISTRY", "TRAVERSALS", "get_traversal",  # noqa: F822
           "Intersector", "INTERSECTOR_REGISTRY", "INTERSECTORS", "get_intersector", "SURFACES"]


@dataclass(frozen=True)
class Traversal:
    """A 2D traversal kernel and what it promises.

    Attributes
    ----------
    name : str
        Public name, used by the API, the CLI and every report.
    kernel_id : int
        Index of the C kernel (``enum hf_kernel`` in ``cext/core/hftrace.h``), read from
        ``algos._kernels.KERNEL_IDS``.
    exact : bool
        True: equals ``reference_cells`` of the lattice-rounded ray (``algos.lattice``)
        on every input within the documented limits. False: a float kernel, measured.
    family : str
        ``"cell"`` (one step per cell) or ``"run"`` (one step per run).
    precision : str
        ``"exact"``, ``"float64"`` or ``"float32"``.
    shared_direction : bool
        Designed for batches of parallel rays; the per-direction setup (here the run
        pattern) is reused while consecutive rays share a direction.
    exact_when : str
        The condition under which an approximate kernel is still exact.
    citation : str
    """

    name: str
    kernel_id: int
    exact: bool
    family: str
    precision: str
    shared_direction: bool = False
    exact_when: str = ""
    citation: str = ""
    summary: str = ""
    #: a registered plugin's calling details (``algos.plugins.Plugin``); None when built in
    plugin: object = None


TRAVERSAL_REGISTRY: dict[str, Traversal] = {
    t.name: t
    for t in (
        Traversal(
            "dda", _C_ID["dda"], False, "cell", "float64",
            citation="Amanatides & Woo 1987",
            summary="cell DDA, float64, incremental tMax += tDelta (the baseline)",
        ),
        Traversal(
            "dda_f32", _C_ID["dda_f32"], False, "cell", "float32",
            citation="Amanatides & Woo 1987",
            summary="cell DDA in float32 (the stability baseline)",
        ),
        Traversal(
            "midpoint", _C_ID["midpoint"], True, "cell", "exact",
            citation="Bresenham 1965; midpoint decision variable",
            summary="4-connected walk, exact integer decision variable",
        ),
        Traversal(
            "runs", _C_ID["runs"], True, "run", "exact",
            citation="Henning & Stephenson 2004",
            summary="run-based walk, exact integer run recurrence with start clipping",
        ),
        Traversal(
            "runs_f64", _C_ID["runs_f64"], False, "run", "float64",
            citation="Henning & Stephenson 2004",
            summary="the run recurrence in float64 (the paper's float formulation)",
        ),
        Traversal(
            "runs_periodic", _C_ID["runs_periodic"], False, "run", "exact",
            shared_direction=True,
            exact_when="the reduced slope is p/q with q <= max_denominator",
            citation="Henning & Stephenson 2004",
            summary="replays the periodic run pattern of a rational slope p/q",
        ),
    )
}

#: Called, in order, when a name is not registered, before the lookup is refused: a hook
#: may register more kernels (``algos.plugins`` adds the one that loads the installed
#: packages' entry points), so that this module imports no other.
MISS_HOOKS: list = []


def _after_miss(name, table):
    """The entry for ``name`` once the :data:`MISS_HOOKS` ran, or None."""
    if not isinstance(name, str):
        return None
    for hook in MISS_HOOKS:
        hook()
    return table.get(name)


def get_traversal(name: str) -> Traversal:
    """The registry entry for ``name``; ``ValueError`` listing the valid names otherwise."""
    try:
        return TRAVERSAL_REGISTRY[name]
    except (KeyError, TypeError):
        found = _after_miss(name, TRAVERSAL_REGISTRY)
        if found is not None:
            return found
        if isinstance(name, str) and name in INTERSECTOR_REGISTRY:
            raise ValueError(f"name: {name!r} is a first-hit intersector; it has no 2D "
                             "traversal kernel (algos.intersect serves it)") from None
        raise ValueError(
            f"name: unknown traversal {name!r}; valid names are {', '.join(TRAVERSAL_REGISTRY)}"
        ) from None


# ---- intersectors --------------------------------------------------------------------
#: Cell surfaces (docs/CONVENTIONS.md, "Cell surfaces"), in the C enum's order.
SURFACES = ("flat", "plane3", "triangles", "bilinear")


@dataclass(frozen=True)
class Intersector:
    """A first-hit algorithm for ``algos.intersect`` and what it promises.

    Attributes
    ----------
    kernel_id : int or None
        The C intersector (``cext/core/hftrace.h``, read from ``algos._kernels.KERNEL_IDS``);
        None for a peer run from Python.
    kind : str
        ``"traversal"`` (a 2D traversal plus per-cell tests), ``"maxmip"``,
        ``"compact"`` (the compact maximum tree, ``algos.accel.compact``),
        ``"cone"`` (cone step mapping, ``algos.accel.cone``), ``"march"`` (ray marching),
        ``"peer"`` or ``"plugin"`` (registered through ``algos.plugins``).
    accuracy : str
        ``"exact"``: exact traversal, float64 surface tests; equals the brute force up
        to ``|dt| <= 1e-9 (1 + |t|)``. ``"float64"``/``"float32"``: the traversal's own
        precision. ``"approximate"``: by design (marching). ``"float32-peer"``: Embree.
    structures : tuple of str
        The ``algos.field.Field`` structures it reads (built only when used).
    options : dict
        Keyword options of ``intersect`` it takes, with defaults.
    """

    name: str
    kernel_id: int | None
    kind: str
    accuracy: str
    traversal: str | None = None
    structures: tuple = ()
    options: dict = None
    surfaces: tuple = SURFACES
    summary: str = ""
    citation: str = ""
    #: a registered plugin's calling details (``algos.plugins.Plugin``); None when built in
    plugin: object = None


_CULL = {"cull_cells": True}
_RUN_CULL = {"cull_cells": True, "cull_runs": True}
_MARCH = {"march_steps": 128}

INTERSECTOR_REGISTRY: dict[str, Intersector] = {}
for _t in TRAVERSAL_REGISTRY.values():
    _runs = _t.family == "run"
    _opts = dict(_RUN_CULL if _runs else _CULL)
    if _t.shared_direction:
        _opts["max_denominator"] = None
    INTERSECTOR_REGISTRY[_t.name] = Intersector(
        _t.name, _t.kernel_id, "traversal",
        "exact" if _t.precision == "exact" else _t.precision, _t.name,
        ("cellmax", "row_max", "col_max") if _runs else ("cellmax",), _opts,
        summary=f"{_t.summary}; per-cell culling" + ("; per-run culling" if _runs else ""),
        citation=_t.citation)
INTERSECTOR_REGISTRY.update({
    "dda_maxmip": Intersector(
        "dda_maxmip", _C_ID["dda_maxmip"], "maxmip", "float64", "dda", ("cellmax", "mip"),
        dict(cull_cells=True, fine_level=3),
        summary="maximum-mipmap tile skipping, a tight cell walk inside 2^fine_level tiles",
        citation="Tevs, Ihrke & Seidel 2008"),
    "packet_maxmip": Intersector(
        "packet_maxmip", _C_ID["packet_maxmip"], "maxmip", "float64", "dda", ("cellmax", "mip"),
        dict(cull_cells=True, fine_level=3, packet_width=4),
        summary="dda_maxmip's walk for packets of packet_width consecutive rays (camera or "
                "parallel batches): one read of a tile's maximum per group of rays over it, "
                "exit parameters side by side; bit-identical to dda_maxmip",
        citation="Wald et al. 2001; Tevs, Ihrke & Seidel 2008"),
    "plane_maxmip": Intersector(
        "plane_maxmip", _C_ID["plane_maxmip"], "maxmip", "float64", "dda", ("cellmax", "mip"),
        dict(cull_cells=True, fine_level=3),
        summary="dda_maxmip's walk with vertical-plane coherence: rays sharing an origin and "
                "a horizontal direction (bit for bit) are traced bottom up, each resuming "
                "where the ray below hit (flat, plane3, triangles; bilinear rays and rays "
                "without a partner walk alone); bit-identical to dda_maxmip",
        citation="Cohen-Or & Shaked 1993; Lee & Shin 1995; Tevs, Ihrke & Seidel 2008"),
    "pitched_maxmip": Intersector(
        "pitched_maxmip", _C_ID["pitched_maxmip"], "maxmip", "float64", "dda", ("cellmax", "mip"),
        dict(cull_cells=True, fine_level=3),
        summary="dda_maxmip's walk started at a conservative lower bound on the hit, read "
                "from a coarse image of the max-mipmap tile boxes drawn from the eye; applies "
                "to batches whose rays share one origin bit for bit (a pinhole camera at any "
                "pitch), the others walk from their start; bit-identical to dda_maxmip",
        citation="Warnock 1969; Tevs, Ihrke & Seidel 2008"),
    "ring_maxmip": Intersector(
        "ring_maxmip", _C_ID["ring_maxmip"], "maxmip", "float64", "dda", ("cellmax", "mip"),
        dict(cull_cells=True, fine_level=3),
        summary="dda_maxmip's walks of independent rays, 8 in flight and advanced one step "
                "(a tile test, a descent or a floor tile) in turn, with a software prefetch "
                "of each ray's next tile maximum and floor-tile cells from its 2D line; "
                "bit-identical to dda_maxmip, statistics included",
        citation="Kocberber, Falsafi & Grot 2015; Tevs, Ihrke & Seidel 2008"),
    "runs_maxmip": Intersector(
        "runs_maxmip", _C_ID["runs_maxmip"], "maxmip", "exact", "runs",
        ("cellmax", "mip"), dict(cull_cells=True, cull_runs=False, fine_level=3),
        summary="maximum-mipmap tile skipping, exact runs inside 2^fine_level tiles "
                "(run culling off by default: the mipmap already rejects what it would)",
        citation="Tevs, Ihrke & Seidel 2008; Henning & Stephenson 2004"),
    "cone": Intersector(
        "cone", _C_ID["cone"], "cone", "float64", "dda", ("cellmax", "cone"), dict(cull_cells=True),
        summary="cone step mapping made exact: safe steps through per-cell cones over the "
                "cell maxima, an exact cell walk where a cone is narrower than a cell",
        citation="Dummer 2006"),
    "dda_compact": Intersector(
        "dda_compact", _C_ID["dda_compact"], "compact", "float64", "dda", ("cellmax", "compact"),
        dict(cull_cells=True),
        summary="maximum-tree tile skipping on a cache-compact 4 x 4-ary tree (one 64-byte "
                "node per line, uint16 maxima rounded up; uint8 cell codes, 8 x 8 cells a "
                "line), a tight cell walk in 4 x 4 tiles",
        citation="Tevs, Ihrke & Seidel 2008"),
    "cone_relaxed": Intersector(
        "cone_relaxed", _C_ID["cone_relaxed"], "march", "approximate", None, ("cellmax", "cone_relaxed"),
        dict(march_steps=256, march_refinements=16),
        summary="relaxed cone stepping: steps to the side of relaxed cones over the cell "
                "maxima (at most march_steps), then march_refinements halvings; misses "
                "ridges a step crosses whole",
        citation="Policarpo & Oliveira 2007"),
    "march_linear": Intersector(
        "march_linear", _C_ID["march_linear"], "march", "approximate", None, (), dict(_MARCH),
        summary="fixed-step ray marching: march_steps equal steps over the clipped span"),
    "march_growing": Intersector(
        "march_growing", _C_ID["march_growing"], "march", "approximate", None, (),
        {"march_growth": 1.02, "march_first_fraction": 1 / 580, "march_min_step": 0.0},
        summary="ray marching whose step grows 2 % per step from 1/580 of the span"),
    "march_binary": Intersector(
        "march_binary", _C_ID["march_binary"], "march", "approximate", None, (),
        dict(_MARCH, march_refinements=16),
        summary="the linear search followed by march_refinements halvings"),
    "embree": Intersector(
        "embree", None, "peer", "float32-peer", None, ("embree",), {}, ("triangles",),
        summary="Intel Embree through embreex on the same triangles, single ray at a time",
        citation="Wald et al. 2014"),
})


def _register_embree3():
    """The C Embree 3 peer (``algos.peers.embree3``), registered next to ``embree`` only
    where it is built (setup.py finds embree3/rtcore.h); elsewhere it is absent."""
    from importlib.util import find_spec

    try:
        if find_spec("algos._embree3") is None:
            return
    except (ImportError, ValueError):
        return
    INTERSECTOR_REGISTRY["embree3"] = Intersector(
        "embree3", None, "peer", "float32-peer", None, ("embree3",),
        {"geometry": "grid", "packet": 1, "coherent": False}, ("triangles",),
        summary="Intel Embree 3 from C (system libembree-dev): the grid geometry laid out "
                "on the conventions' split (or geometry='triangles'), single rays or packets "
                "of 4/8/16 (packet=), no robust mode, high build quality",
        citation="Wald et al. 2014")


_register_embree3()


def get_intersector(name: str) -> Intersector:
    """The registry entry for ``name``; ``ValueError`` listing the valid names otherwise."""
    try:
        return INTERSECTOR_REGISTRY[name]
    except (KeyError, TypeError):
        found = _after_miss(name, INTERSECTOR_REGISTRY)
        if found is not None:
            return found
        if isinstance(name, str) and name in TRAVERSAL_REGISTRY:
            raise ValueError(f"name: {name!r} is a 2D traversal (the visit workload); it has "
                             "no first-hit kernel (algos.traverse serves it)") from None
        raise ValueError(
            f"name: unknown intersector {name!r}; valid names are "
            f"{', '.join(INTERSECTOR_REGISTRY)}"
        ) from None


def __getattr__(name):
    """``TRAVERSALS`` and ``INTERSECTORS``: the registered names, in registry order, read
    from the tables at each access, so that a plugin registered later (``algos.plugins``)
    is listed without any module having to refresh a copy."""
    if name == "TRAVERSALS":
        return tuple(TRAVERSAL_REGISTRY)
    if name == "INTERSECTORS":
        return tuple(INTERSECTOR_REGISTRY)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
