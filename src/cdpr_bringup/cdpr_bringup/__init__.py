"""Robot and scenario configs, the scripts that start the cdpr graph, bag recording, scenario runner, reports and benchmarks."""
