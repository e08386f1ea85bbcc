"""The asv suite (``asv run``, ``make history``): the kernels' time and exact counts per
commit, kept by asv outside the source tree (``.asv/``)."""
