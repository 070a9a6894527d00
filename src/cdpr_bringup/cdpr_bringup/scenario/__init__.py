"""`cdpr-scenario`: one run, through the node graph or in-process, written as run.yaml,
bag, metrics.json and plots.

Rooms it may import: runs, bags, reports, graph.
"""
