"""The robot: its cables, motors and end-effector, the interface every body implements
(body.py), and the joint-space reference table of either body.

Rooms it may import: geometry, tension_distribution.
"""
