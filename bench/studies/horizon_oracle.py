"""How much of the chain walk's work a better lower bound could save (issue 31, item 4):
the walk of every vertex with the bounds it borrows (``algos.terrain.chain_neighbours``)
against the same walk started from an oracle, its own exact horizon (a bound no method
can beat), on the same strips. Counts, not times: cells evaluated, cells stepped past by
their corners, strip tests and strip skips per vertex (``hf_chain_stats``), and whether
the angles are bit-identical (they must be: a bound only prunes).

The oracle reads each vertex's own occluder through the neighbour (0, 0) with distance 0
(``hf_horizon_chain`` reads ``occ`` of a neighbour as it is on entry: for (0, 0), the
occluder a first walk left there). docs/terrain.md gives the figures.

    python -m bench.studies.horizon_oracle [--dataset jacksboro] [--size 2048] [--azimuth 22.5]
"""
from __future__ import annotations

import argparse

import numpy as np

FIELDS = ("cells", "skips", "tile_tests", "bounded", "cell_skips")


def chain_counts(heights, azimuth):
    """Walk every vertex of ``heights`` ((rows, cols) float64, cell units) at ``azimuth``
    (degrees) twice: with the borrowed bounds, then with the oracle. Returns
    ``(borrowed, oracle, same)``: two dicts of counts per vertex (:data:`FIELDS`) and
    whether the two outputs are bit-identical."""
    from algos import _kernels
    from algos.terrain.directions import azimuth_direction
    from algos.terrain.walks import CHAIN_BLOCK_ROWS, chain_neighbours, chain_strips

    h = np.ascontiguousarray(heights, dtype=np.float64)
    rows, cols = h.shape
    d = azimuth_direction(azimuth)
    strips, _ = chain_strips(h, d)
    blocks = -(-rows // CHAIN_BLOCK_ROWS)

    def walk(nb, occ):
        out = np.empty(rows * cols)
        counts = _kernels.horizon_chain(h, strips, d.dx, d.dy, np.inf, *nb, CHAIN_BLOCK_ROWS,
                                        0, blocks, out, occ)
        return out, dict(zip(FIELDS, (c / (rows * cols) for c in counts[1:])))

    occ = np.full(rows * cols, np.nan)
    out, borrowed = walk(chain_neighbours(d), occ)
    self_nb = (np.zeros(1, np.int64), np.zeros(1, np.int64), np.zeros(1))
    out_oracle, oracle = walk(self_nb, occ.copy())
    return borrowed, oracle, bool(np.array_equal(out, out_oracle, equal_nan=True))


def main(argv=None):
    """The command line (module docstring): prints the counts per vertex as a Markdown
    table; exit status 1 when the angles differ (a bound may only prune)."""
    p = argparse.ArgumentParser(prog="python -m bench.studies.horizon_oracle",
                                description=__doc__.split("\n\n")[0])
    p.add_argument("--dataset", default="jacksboro")
    p.add_argument("--size", type=int, default=2048)
    p.add_argument("--azimuth", type=float, default=22.5)
    args = p.parse_args(argv)
    import datasets_gen

    field = datasets_gen.load(args.dataset, size=args.size)
    spacing = np.atleast_1d(field.spacing)[0] if field.spacing is not None else 1.0
    heights = np.asarray(field.heights, dtype=np.float64) / spacing  # cell units
    borrowed, oracle, same = chain_counts(heights, args.azimuth)
    print(f"{args.dataset} {heights.shape[0]} x {heights.shape[1]}, azimuth {args.azimuth:g}: "
          f"per vertex (bit-identical angles: {same})")
    print("| bound | " + " | ".join(FIELDS) + " |")
    print("|---|" + "---|" * len(FIELDS))
    for name, c in (("borrowed", borrowed), ("oracle", oracle)):
        print(f"| {name} | " + " | ".join(f"{c[k]:.2f}" for k in FIELDS) + " |")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
