"""What a run's files say: the robot file (the one place a robot's body is chosen) and
the settings every node takes.

Rooms it may import: model, point_mass, platform, geometry, tension_distribution.
"""
