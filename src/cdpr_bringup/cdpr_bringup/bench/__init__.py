"""`cdpr-bench`: every suite (model, run, cycle, graph, recorder, soak, fdi, roc, sweep,
campaign, far), each a module of this room; robots, the family room's.

Rooms it may import: runs, bags, reports, graph, scenario, campaigns, family.
"""
