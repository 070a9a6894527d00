"""The rigid platform (3 rotations + 3 translations): its body (body.py) and its
equations — kinematics, statics, Newton–Euler dynamics, its motions with a turn,
reference tabulation, compiled sub-steps, the safe pose search and the steered approach.

Rooms it may import: model, geometry, tension_distribution.
"""
