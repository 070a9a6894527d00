"""The node graph: start and stop it (`cdpr-graph`, `launcher`), the composed loop, the
launch files' side (`launch_files`) and the params files (`cdpr-params`).

Rooms it may import: runs.
"""
