"""Everything above the nodes' cores: runs, bags, reports, the node graph, the scenario
command, campaigns and benchmarks, each in a room (a subpackage) whose docstring names the
rooms it may import; `cli` and `paths` are the base every room may use.
docs/architecture.md draws the house."""
