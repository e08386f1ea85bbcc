"""Studies that are library modules first: each has a ``run(out_dir, quick=True)``."""
