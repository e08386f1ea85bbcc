"""The one registry of algorithms: name -> kernel, reference and properties.

Tests, benchmarks, the CLI and the reports iterate over :data:`TRAVERSAL_REGISTRY`; none
keeps a list of its own.
"""
from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Traversal", "TRAVERSAL_REGISTRY", "TRAVERSALS", "get_traversal"]


@dataclass(frozen=True)
class Traversal:
    """A 2D traversal kernel and what it promises.

    Attributes
    ----------
    name : str
        Public name, used by the API, the CLI and every report.
    kernel_id : int
        Index of the C kernel (``enum hf_kernel`` in ``cext/hftrace.h``).
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


TRAVERSAL_REGISTRY: dict[str, Traversal] = {
    t.name: t
    for t in (
        Traversal(
            "dda", 0, False, "cell", "float64",
            citation="Amanatides & Woo 1987",
            summary="cell DDA, float64, incremental tMax += tDelta (the baseline)",
        ),
        Traversal(
            "dda_f32", 1, False, "cell", "float32",
            citation="Amanatides & Woo 1987",
            summary="cell DDA in float32 (the stability baseline)",
        ),
        Traversal(
            "midpoint", 2, True, "cell", "exact",
            citation="Bresenham 1965; midpoint decision variable",
            summary="4-connected walk, exact integer decision variable",
        ),
        Traversal(
            "runs", 3, True, "run", "exact",
            citation="Henning & Stephenson 2004",
            summary="run-based walk, exact integer run recurrence with start clipping",
        ),
        Traversal(
            "runs_f64", 4, False, "run", "float64",
            citation="Henning & Stephenson 2004",
            summary="the run recurrence in float64 (the paper's float formulation)",
        ),
        Traversal(
            "runs_periodic", 5, False, "run", "exact",
            shared_direction=True,
            exact_when="the reduced slope is p/q with q <= max_denominator",
            citation="Henning & Stephenson 2004",
            summary="replays the periodic run pattern of a rational slope p/q",
        ),
    )
}

#: Names of the 2D traversal kernels, in registry order.
TRAVERSALS: tuple[str, ...] = tuple(TRAVERSAL_REGISTRY)


def get_traversal(name: str) -> Traversal:
    """The registry entry for ``name``; ``ValueError`` listing the valid names otherwise."""
    try:
        return TRAVERSAL_REGISTRY[name]
    except (KeyError, TypeError):
        raise ValueError(
            f"name: unknown traversal {name!r}; valid names are {', '.join(TRAVERSALS)}"
        ) from None
