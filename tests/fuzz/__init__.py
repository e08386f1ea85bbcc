"""The fuzz harness of ``make fuzz`` (``harness.py``)."""
