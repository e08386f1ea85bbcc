"""The workload the scaling studies share (``bench.studies.threads``, ``growth`` and
``big``, run together by ``bench.studies.scaling``): the fBm field, the ray set at one
run length, the grid sides and the constants."""
from __future__ import annotations

import algos
from datasets_gen import fields
from datasets_gen import rays as raysets

__all__ = ["fbm_field", "growth_rays", "SIDES", "GROWTH_R", "GROWTH_ELEVATION", "EMBREE_MAX_SIDE"]

SIDES = (256, 512, 1024, 2048, 4096, 8192, 16384)
GROWTH_R = 25
GROWTH_ELEVATION = 10.0
#: Embree's scene for a 8192^2 field is about 134 M triangles (some 10 GB measured at
#: 2048^2 x 16); the growth study stops it at this side by default
EMBREE_MAX_SIDE = 4096


def fbm_field(side, seed=1) -> algos.Field:
    """The studies' field: fBm of ``side`` x ``side`` samples (``datasets_gen.fields``)."""
    return algos.Field(fields.generate("fbm", side, seed=seed))


def growth_rays(field, n, seed):
    """Rays at run length GROWTH_R falling at GROWTH_ELEVATION degrees from one cell above
    the highest point, origins uniform over the field."""
    rows, cols = field.rows, field.cols
    rs = raysets.by_run_length(GROWTH_R, n, (cols - 1, rows - 1), seed, origins="inside",
                               elevation=GROWTH_ELEVATION, height=field.hmax + 1.0)
    return rs.origins, rs.directions
