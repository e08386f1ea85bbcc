"""The pytest-benchmark suite (``make bench-ci``)."""
