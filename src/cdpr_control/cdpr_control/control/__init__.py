"""The controller and the trajectory generator: PD + feed-forward in joint space, the
setpoints it follows, the reference schedule, and their nodes.

Rooms it may import: setup, model, geometry, tension_distribution, point_mass (a goal
move is a point's path, tabulated as one; Body.check_goal refuses a goal to any other).
"""
