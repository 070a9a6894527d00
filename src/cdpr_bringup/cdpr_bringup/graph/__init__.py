"""The node graph: start and stop it (`cdpr-graph`, `launcher`), the composed loop, the
launch files' side (`launch_files`), the params files (`cdpr-params`), and an outside
reader of its topics, as a user's tool would be (`outside_reader`: the recorder bench and
the outside-reader tests start it).

Rooms it may import: runs.
"""
