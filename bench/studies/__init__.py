"""The studies: one module per study, each run by an ``hftrace`` command (``bench.cli``)."""
