"""`cdpr-bench`: every suite (model, run, cycle, graph, recorder, soak, fdi, roc, sweep,
campaign), each a module of this room, and the outside reader the graph suites start.

Rooms it may import: runs, bags, reports, graph, scenario, campaigns.
"""
