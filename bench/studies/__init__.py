"""The studies: one module per study, each run by an ``hftrace`` command (``bench.cli``);
each has a ``run(out_dir, ...)`` entry point."""
