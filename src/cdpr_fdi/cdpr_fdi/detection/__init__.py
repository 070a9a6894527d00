"""What the supervisor reads off the motors: torque residuals and sensorless tensions, the
tension collapse, the wrench balance that tells a push from a break, identification, the
detectors' thresholds from failure-free runs (calibration), where a break hides from the
residual (visibility) and their compiled per-tick arithmetic.

Rooms it may import: none.
"""
