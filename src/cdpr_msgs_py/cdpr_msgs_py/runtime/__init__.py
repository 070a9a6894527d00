"""The node runtime: what every cdpr node is and does besides its core, split by job.

- `spin`: the executor, running one node or a composed group, the drain and clean
  shutdown, the ready mark and stack dump the launchers use;
- `acknowledgements`: watching that each per-cycle writer's readers keep up;
- `diagnostics`: counts, health and the /diagnostics status;
- `subscriptions`: subscriptions that obey one writer (the contract's sole-writer rule),
  and the second look at the ROS graph that pins a writer the node's graph lost the name of;
- `publishers`: publishers whose failure is counted, never fatal;
- `parameters`: declaring a node's parameters with descriptions and ranges;
- `handshake`: the start handshake (subscribe to the tick once every peer is matched);
- `node`: `CdprNode`, a node of the graph, made of the above.

The interface contract (topics, QoS, conversions) is beside it in `cdpr_msgs_py`, its
base, and nothing there imports the runtime.

Rooms it may import: none.
"""
