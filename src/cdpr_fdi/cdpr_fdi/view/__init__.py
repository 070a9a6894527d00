"""What RViz and Foxglove draw of a run: the markers' shapes of each view tick, from numpy
inputs, for the markers node and an in-process run's bag.

Rooms it may import: settings, recovery_planning.
"""
