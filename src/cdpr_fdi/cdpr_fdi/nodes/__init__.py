"""The `supervisor` and `markers` nodes: thin ROS shells around the supervision and view
rooms' cores.

Rooms it may import: settings, supervision, view, recovery_planning.
"""
