"""The controller and the trajectory generator: PD + feed-forward in joint space, the
setpoints it follows, the reference schedule, and their nodes.

Rooms it may import: setup, model, geometry, tension_distribution.
"""
