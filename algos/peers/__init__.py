"""Peers: other people's ray tracers on the same triangles (docs/CONVENTIONS.md,
"Embree comparisons"), the ground truth and the times to beat.

* :mod:`~algos.peers.embree`: Embree through ``embreex`` (single-ray triangle queries);
* :mod:`~algos.peers.embree3`: the optional C peer against the system Embree 3 (grids,
  triangles, packets), built by setup.py only where Embree 3's headers are found.
"""
