"""The twin's, the plant's and the hardware bridge's nodes, and what they keep between
ticks: the joint mapping, the command watchdog, tick timing, the recorder's pacing and
the run's length.

Rooms it may import: models.
"""
