"""``python -m bench.cli.big_item ITEM SIDE PATH``: one item of the big-field study
(``bench.studies.big.big_item``) in its own process, for its peak RSS; prints the item's
result as one JSON line. It lives with the commands because two items measure them
(``render_files``, ``run_product``), which it hands to the study.
"""
from __future__ import annotations

import json
import sys

from ..studies.big import big_item
from .render import render_files
from .terrain_dask import run_product


def main(argv=None) -> int:
    """Run one item; its JSON result on the last line of standard output."""
    item, side, path = (argv if argv is not None else sys.argv[1:])[:3]
    result = big_item(item, int(side), path,
                      commands={"render_files": render_files, "run_product": run_product})
    print(json.dumps(result, default=str))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
