"""composed_loop: the graph's nodes named on its command line, composed in this one
process on one executor, as `cdpr-graph --graph-form composed` starts the control loop.

    composed_loop NODE [NODE ...] --ros-args -r __ns:=NS --params-file FILE

FILE holds each node's parameters under its own name (`/**/controller:`), as
graph.NodeSpec.parameters_document lays it out. Each node is the very class its own executable runs
(`ros2 run cdpr_control controller`); composed, the messages between them stay inside
this process, handed over as objects without DDS (ROS 2's intra-process communication:
cdpr_msgs_py.runtime.local_bus), and go out on DDS only to readers outside it
(docs/graph.md, "Graph forms").
"""
from __future__ import annotations

import sys
from importlib import import_module

from cdpr_msgs_py import contract
from cdpr_msgs_py.runtime.spin import run_composed

from ..cli import USAGE_EXIT_CODE

# node name: (module, class) of the nodes that may be composed
COMPOSABLE = {
    contract.TRAJECTORY_GENERATOR: ('cdpr_control.control.trajectory_generator_node', 'TrajectoryGeneratorNode'),
    contract.CONTROLLER: ('cdpr_control.control.controller_node', 'ControllerNode'),
    contract.DIGITAL_TWIN: ('cdpr_twin.nodes.digital_twin_node', 'DigitalTwinNode'),
    contract.SUPERVISOR: ('cdpr_fdi.nodes.supervisor_node', 'SupervisorNode'),
    contract.PLANT_SIMULATOR: ('cdpr_twin.nodes.plant_simulator_node', 'PlantSimulatorNode'),
}


def main(args=None) -> int:
    argv = sys.argv[1:] if args is None else list(args)
    names = argv[:argv.index('--ros-args')] if '--ros-args' in argv else argv
    unknown = [name for name in names if name not in COMPOSABLE]
    if not names or unknown:
        print(f'composed_loop: name the nodes to compose, of {", ".join(COMPOSABLE)}'
              + (f'; not composable: {", ".join(unknown)}' if unknown else ''), file=sys.stderr)
        return USAGE_EXIT_CODE
    classes = [getattr(import_module(module), name) for module, name in map(COMPOSABLE.get, names)]
    return run_composed(classes, ['composed_loop', *argv[len(names):]], names)


if __name__ == '__main__':
    sys.exit(main())
