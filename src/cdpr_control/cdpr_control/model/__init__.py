"""The robot: its cables, motors and end-effector, the interface every body implements
(body.py), the joint-space reference table of either body, and its workspace searches
made once (searches.py).

Rooms it may import: geometry, tension_distribution.
"""
