"""Positions, orientations and rest-to-rest motions in space, of no robot: rotations,
small linear algebra, trajectories and the named motions of a motions file.

Rooms it may import: none.
"""
