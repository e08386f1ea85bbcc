"""Acceleration structures: what the walks read to skip cells that cannot be hit.

* :mod:`~algos.accel.maxima`: cell maxima (an upper bound of each cell's surface) and
  their range maxima along rows and columns (run culling);
* :mod:`~algos.accel.mipmap`: the maximum mipmap (Tevs, Ihrke & Seidel 2008), for
  ``dda_maxmip``, ``runs_maxmip`` and the terrain products' tile skips;
* :mod:`~algos.accel.compact`: the cache-compact maximum tree of ``dda_compact``;
* :mod:`~algos.accel.cone`: cone step maps, exact (Dummer 2006) and relaxed (Policarpo &
  Oliveira 2007).

Each module builds arrays from heights and nothing else; :class:`algos.field.HeightField`
builds them on first use and keeps them (build once per field).
"""
