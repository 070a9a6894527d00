"""The point mass (3 translations): its body (body.py) and its equations — kinematics,
statics, dynamics, reference tabulation, compiled sub-steps, the static-equilibrium
workspace.

Rooms it may import: model, geometry, tension_distribution.
"""
