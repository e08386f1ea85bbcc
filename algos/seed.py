"""The run recurrence of Henning & Stephenson (2004) as the seeds state it, in exact
rationals: a readable twin of ``cext/walks/runs.c`` for reading and for tests.

The digital line ``Y(x) = floor(alpha x + beta)``, ``0 < alpha <= 1``, ``0 <= beta < 1``,
sampled at ``x = 0, 1, 2, ...``, is a sequence of runs (maximal stretches with one ``Y``).
Run ``j`` starts at ``x_j`` and ``beta_j = alpha x_j + beta - j`` is how far the line has
risen into row ``j`` there, ``0 <= beta_j < alpha``. The next run starts at the first
``k`` with ``beta_j + alpha k >= 1``, so

    r_j = ceil((1 - beta_j) / alpha),    beta_{j+1} = beta_j + alpha r_j - 1.

With the short length ``r = floor(1/alpha)`` and ``v = 1 - alpha r``:
``r_j = r`` exactly when ``1 - beta_j <= alpha r``, i.e. ``beta_j >= v``. Hence

    beta_j <  v  ->  long  (r + 1),  beta_{j+1} = beta_j + mu,  mu = alpha (r+1) - 1
    beta_j >= v  ->  short (r),      beta_{j+1} = beta_j - v

The slides print the comparison the other way round ("beta_j >= v -> long"); the
derivation above, and ``tests/walks/test_runs_math.py``, show which one holds.

Start clipping (the ray enters its first row ``beta`` above the row's floor): the first
run has ``r_0 = ceil((1 - beta)/alpha) = r - floor((beta - v)/alpha)`` samples, it is
shorter than a short run exactly when ``beta >= alpha + v``, and
``beta_1 = (beta - v) - alpha floor((beta - v)/alpha)``.
"""
from __future__ import annotations

import math
from fractions import Fraction

__all__ = ["seed_run_lengths", "digital_line_run_lengths", "run_pattern"]


def seed_run_lengths(alpha, beta, count: int) -> list[int]:
    """The first ``count`` run lengths of ``floor(alpha x + beta)`` by the recurrence,
    starting with the clipped first run ``r_0``."""
    alpha, beta = Fraction(alpha), Fraction(beta)
    if not (0 < alpha <= 1 and 0 <= beta < 1):
        raise ValueError(f"need 0 < alpha <= 1 and 0 <= beta < 1, got {alpha}, {beta}")
    r = math.floor(1 / alpha)
    v = 1 - alpha * r
    mu = alpha - v
    # start clipping
    shortening = math.floor((beta - v) / alpha)
    lengths = [r - shortening]
    b = (beta - v) - shortening * alpha
    while len(lengths) < count:
        if b < v:
            lengths.append(r + 1)
            b += mu
        else:
            lengths.append(r)
            b -= v
    return lengths


def digital_line_run_lengths(alpha, beta, count: int) -> list[int]:
    """The same run lengths straight from the definition: the number of integers
    ``x >= 0`` with ``floor(alpha x + beta) == j``, for ``j = 0 .. count-1``."""
    alpha, beta = Fraction(alpha), Fraction(beta)
    # run j starts at the smallest x >= 0 with alpha x + beta >= j
    starts = [max(0, math.ceil((j - beta) / alpha)) for j in range(count + 1)]
    return [b - a for a, b in zip(starts, starts[1:])]


def run_pattern(p: int, q: int) -> str:
    """The periodic pattern of slope p/q (lowest terms) from beta = 0, as 'l'/'s' per
    run over one period of p runs (q samples)."""
    lengths = seed_run_lengths(Fraction(p, q), 0, p)
    short = math.floor(Fraction(q, p))
    if Fraction(q, p) == short:
        return "s" * p
    return "".join("l" if n == short + 1 else "s" for n in lengths)
