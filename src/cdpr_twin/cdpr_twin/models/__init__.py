"""The robot as simulated and as its twin models it: the plants (rigid, elastic, field) of
each body, their compiled sub-steps, the plant simulator that breaks cables and measures,
the digital twin, and a run's figures from its truth.

Rooms it may import: none.
"""
