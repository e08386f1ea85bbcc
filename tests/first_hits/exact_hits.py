"""First hits in exact rational arithmetic, for the piecewise linear surfaces (flat,
plane3, triangles): the arbiter when the brute force and the kernels disagree. The
reference lives in :mod:`algos.exact_hits` (the brute force uses it on the rays whose
float64 signs it cannot trust); the tests import it from here."""
from algos.exact_hits import exact_first_hit

__all__ = ["exact_first_hit"]
