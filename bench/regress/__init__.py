"""The CI gates: ``time_gate`` (speedup ratios) and ``instructions_gate`` (callgrind counts), each
with its committed baseline next to it."""
