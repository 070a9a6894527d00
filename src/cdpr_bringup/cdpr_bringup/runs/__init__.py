"""One run without DDS: its options settled in one pass (`settle`), the in-process engine,
the run's record (`recording`) and its figures (`metrics`).

Rooms it may import: none (only the base modules `cli` and `paths`).
"""
