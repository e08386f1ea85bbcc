"""``hftrace list`` (the registered algorithms) and ``hftrace datasets list|show``."""
from __future__ import annotations

import numpy as np

import algos

from .args import add_plugin, load_plugins, param, positive_int


def list_algorithms(args):
    """Print every traversal and intersector of the registry with its properties."""
    load_plugins(args)
    traversals = list(algos.TRAVERSAL_REGISTRY.values())
    intersectors = list(algos.INTERSECTOR_REGISTRY.values())
    exact = {t.name: "exact" if t.exact else (f"exact when {t.exact_when}" if t.exact_when
                                              else t.precision) for t in traversals}
    # columns as wide as their longest entry, so a long name or condition never shifts a row
    name_w = max(len(r.name) for r in traversals + intersectors)
    family_w = max(len(t.family) for t in traversals)
    exact_w = max(map(len, exact.values()))
    kind_w = max(len(a.kind) for a in intersectors)
    accuracy_w = max(len(a.accuracy) for a in intersectors)
    print("traversals (algos.traverse):")
    for t in traversals:
        print(f"  {t.name:{name_w}s} {t.family:{family_w}s} {exact[t.name]:{exact_w}s} {t.summary} "
              f"({t.citation})")
    print("intersectors (algos.intersect):")
    for a in intersectors:
        print(f"  {a.name:{name_w}s} {a.kind:{kind_w}s} {a.accuracy:{accuracy_w}s} {a.summary}")
    from algos.plugins import plugin_names

    if plugin_names():
        print("plugins (algos.plugins; timed and checked like the built-in kernels): "
              + ", ".join(plugin_names()))
    return 0


def list_datasets(args):
    """Print every generator and embedded field with its parameters."""
    import datasets_gen

    for row in datasets_gen.catalogue():
        params = ", ".join(f"{k}={v}" for k, v in row["params"].items())
        print(f"{row['name']:15s} {row['kind']:9s} {row['summary']}")
        print(f"{'':25s} params: {params}")
    return 0


def show_dataset(args):
    """Print one field's shape, height range, spacing and checksum; optionally a preview."""
    import datasets_gen
    from datasets_gen.preview import write_png

    params = dict(args.param or [])
    field = datasets_gen.load(args.name, size=args.size, seed=args.seed,
                              use_cache=not args.no_cache, cache_dir=args.cache_dir, **params)
    h = field.heights
    print(f"name      {field.name}")
    print(f"shape     {h.shape[0]} rows x {h.shape[1]} cols of samples, {h.shape[0] - 1} x {h.shape[1] - 1} cells")
    print(f"heights   [{float(np.nanmin(h)):.4f}, {float(np.nanmax(h)):.4f}] {field.height_unit}, "
          f"mean {float(np.nanmean(h)):.4f}")
    print(f"spacing   dx {field.dx:g}, dy {field.dy:g} {field.unit}"
          f"{f', CRS {field.crs}' if field.crs is not None else ''}")
    print(f"sha256    {field.checksum}")
    if args.png:
        write_png(args.png, h)
        print(f"preview   {args.png}")
    return 0


def register(sub):
    """Add ``list`` and ``datasets`` to the sub-parsers ``sub``."""
    p = sub.add_parser("list", help="list the registered algorithms (plugins included)")
    add_plugin(p)
    p.set_defaults(func=list_algorithms)

    p = sub.add_parser("datasets", help="the catalogue of height fields (alone: `datasets list`)")
    p.set_defaults(func=list_datasets)  # `hftrace datasets` alone lists them, as `list` does
    dsub = p.add_subparsers(dest="datasets_command")
    q = dsub.add_parser("list", help="every generator and embedded field with its parameters")
    q.set_defaults(func=list_datasets)
    q = dsub.add_parser("show", help="shape, range, spacing and checksum of one field")
    q.add_argument("name")
    q.add_argument("--size", type=positive_int, default=None,
                   help="side in samples (generators: default 256; jacksboro: longer side)")
    q.add_argument("--seed", type=int, default=0)
    q.add_argument("--param", type=param, action="append", metavar="NAME=VALUE",
                   help="a generator parameter (repeatable)")
    q.add_argument("--png", default=None, help="write a hillshaded preview here")
    q.add_argument("--no-cache", action="store_true", help="neither read nor write the cache")
    q.add_argument("--cache-dir", default=None, help="cache location (default: $HFTRACE_CACHE "
                   "or ~/.cache/hftrace)")
    q.set_defaults(func=show_dataset)
