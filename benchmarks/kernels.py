"""asv benchmarks of the headline first-hit kernels on the workload of ``hftrace compare``.

Each benchmark file is taken from the current checkout while asv installs the commit
under test, so this file uses only APIs every commit of the history has: ``algos.Field``,
``algos.intersect``, ``algos.intersect.prepare_timed_intersect`` and
``datasets_gen.rays.by_run_length``. Inputs are seeded: fBm 512^2 (seed 1), 4000 rays at
mean run length 25 (seed 2008) falling 5 to 20 degrees from one cell above the highest
point, on the ``triangles`` surface.

- ``time_first_hit``: one batch of rays traced in C (asv's own timer around the call).
- ``track_*_per_ray``: the exact algorithmic counters (``algos.STATS``) per ray.
- ``track_instructions_per_ray``/``track_branches_per_ray``: callgrind counts of the
  extension's own code per ray (``bench.regress.instructions_gate``); skipped without
  valgrind.
"""
import shutil

import numpy as np

#: the headline first-hit kernels (the tier of ``hftrace compare``'s default)
KERNELS = ["dda", "midpoint", "runs", "dda_maxmip", "runs_maxmip", "cone", "dda_compact"]
SIZE = 512          # fBm side, seed 1
RAYS = 4000         # rays per batch
R = 25              # mean run length of the rays
SEED = 2008         # the rays' seed
SURFACE = "triangles"


def _inputs():
    """(field, origins, directions), seeded."""
    import algos
    import datasets_gen
    from datasets_gen import rays as raysets

    heights = datasets_gen.load("fbm", size=SIZE, seed=1).heights
    rs = raysets.by_run_length(R, RAYS, (SIZE - 1, SIZE - 1), SEED, origins="inside",
                               order="octant", elevation=(5.0, 20.0),
                               height=float(heights.max()) + 1.0)
    return algos.Field(heights), rs.origins, rs.directions


class FirstHit:
    """Time of one batch per kernel."""

    params = [KERNELS]          # the first-hit kernel
    param_names = ["kernel"]
    timeout = 300

    def setup(self, kernel):
        from algos.intersect import prepare_timed_intersect

        field, o, d = _inputs()
        self.run, _ = prepare_timed_intersect(kernel, field, o, d, surface=SURFACE)
        self.run()  # warm: page faults and predictors

    def time_first_hit(self, kernel):
        self.run()


class Counters:
    """The exact counters per ray: the same integers on every machine and compiler."""

    params = [KERNELS]          # the first-hit kernel
    param_names = ["kernel"]
    unit = "per ray"

    def setup_cache(self):
        import algos

        field, o, d = _inputs()
        out = {}
        for kernel in KERNELS:
            hits = algos.intersect(kernel, field, o, d, surface=SURFACE, outputs=("t", "stats"))
            out[kernel] = {k: float(np.mean(v)) for k, v in hits.stats.items()}
        return out

    def track_cells_visited_per_ray(self, counts, kernel):
        return counts[kernel]["cells_visited"]

    def track_cells_tested_per_ray(self, counts, kernel):
        return counts[kernel]["cells_tested"]

    def track_runs_visited_per_ray(self, counts, kernel):
        return counts[kernel]["runs_visited"]

    def track_tiles_skipped_per_ray(self, counts, kernel):
        return counts[kernel]["tiles_skipped"]


class Instructions:
    """callgrind instructions and branches per ray (the gate's inputs: fBm 256^2, 200 rays)."""

    params = [KERNELS]          # the first-hit kernel
    param_names = ["kernel"]
    unit = "per ray"
    timeout = 900

    def setup_cache(self):
        if shutil.which("valgrind") is None:
            return None
        from bench.regress import instructions_gate as gate

        wanted = {gate.key("first_hit", SURFACE, k) for k in KERNELS}
        return gate.measure(echo=lambda *_: None, only=wanted)

    def setup(self, counts, kernel):
        if counts is None:
            raise NotImplementedError("valgrind is not on PATH")

    def track_instructions_per_ray(self, counts, kernel):
        return counts[f"first_hit/{SURFACE}/{kernel}"]["instructions_per_ray"]

    def track_branches_per_ray(self, counts, kernel):
        return counts[f"first_hit/{SURFACE}/{kernel}"]["branches_per_ray"]
