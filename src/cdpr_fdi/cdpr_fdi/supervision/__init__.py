"""The supervisor's core on each tick (residual, detection, identification, recovery), the
twin and supervisor stepped together without ROS (`monitor`), and their replay on
recorded ticks (`offline`).

Rooms it may import: detection, detectors, recovery_planning, recovery_strategies, settings.
"""
