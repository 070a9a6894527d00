"""The FDI and recovery settings (`fdi`, `recovery`) from the robot file and a calibration
file, checked against the detectors and strategies they name.

Rooms it may import: detectors, recovery_strategies.
"""
