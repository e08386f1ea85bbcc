"""Height fields and ray sets: seeded generators, the embedded DEM, loaders, the cache.

>>> import datasets_gen
>>> field = datasets_gen.load("fbm", size=256, seed=1)
>>> field.heights.shape, field.heights.dtype
((256, 256), dtype('float32'))
"""
from __future__ import annotations

from .cache import cache_dir, cached_array
from .fields import GENERATORS, first_sentence, generate
from .loaders import HeightField, jacksboro, load_file, open_lazy, undeclared_nodata
from .raster import create_product, read_raster, save_product, write_product, write_window
from .rays import RaySet

__all__ = ["load", "catalogue", "GENERATORS", "generate", "HeightField", "load_file", "open_lazy",
           "jacksboro", "RaySet", "cache_dir", "EMBEDDED", "read_raster", "write_product",
           "create_product", "write_window", "save_product", "undeclared_nodata"]

#: Real terrain shipped with (or through) the project: name -> (loader, parameters).
EMBEDDED = {
    "jacksboro": (jacksboro, {"vertical_scale": 1.0}),
}


def catalogue() -> list[dict]:
    """Every generator and embedded field with its parameters and defaults."""
    rows = [dict(name=g.name, kind="generator", summary=g.summary,
                 params=dict(size=256, seed=0, **g.defaults), version=g.version)
            for g in GENERATORS.values()]
    for name, (function, defaults) in EMBEDDED.items():
        rows.append(dict(name=name, kind="embedded",
                         summary=first_sentence(function.__doc__),
                         params=dict(size=None, **defaults), version=1))
    return rows


def load(name, *, size=None, seed=0, use_cache=True, cache_dir=None, **params) -> HeightField:
    """A named height field: a generator (``size``, default 256, ``seed`` and its
    parameters) or an embedded one (``jacksboro``: ``size`` is the longer side, default
    native resolution).

    Generated fields are cached on disk (see :mod:`datasets_gen.cache`); pass
    ``use_cache=False`` to bypass the cache.
    """
    if name in EMBEDDED:
        function, defaults = EMBEDDED[name]
        unknown = set(params) - set(defaults)
        if unknown:
            raise ValueError(f"{sorted(unknown)[0]}: not a parameter of {name}; it takes "
                             f"{', '.join(defaults)}")
        return function(size=size, use_cache=use_cache, cache_dir=cache_dir, **params)
    if name not in GENERATORS:
        names = list(GENERATORS) + list(EMBEDDED)
        raise ValueError(f"name: unknown dataset {name!r}; valid names are {', '.join(names)}")
    gen = GENERATORS[name]
    size = 256 if size is None else size
    description = dict(kind="generator", name=name, size=size, seed=seed, version=gen.version,
                       params={**gen.defaults, **params})
    heights = cached_array(description, lambda: generate(name, size, seed, **params),
                           use_cache=use_cache, directory=cache_dir)
    return HeightField(heights, name, params=dict(size=size, seed=seed, **params))
