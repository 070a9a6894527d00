"""Bags: MCAP writing and reading (`bag_io`, `bulk_cdr`), the `bag_recorder` node and its
count of the ticks it never received (`tick_gaps`).

Rooms it may import: runs.
"""
