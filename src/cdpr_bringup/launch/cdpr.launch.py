"""The whole cdpr graph, as `cdpr-graph` starts it: `ros2 launch cdpr_bringup cdpr.launch.py`.

Arguments are cdpr-graph's options (`ros2 launch cdpr_bringup cdpr.launch.py --show-args`):
config (robot file or set-up), motions, motion, fidelity, clock, graph_form, detector,
calibration, fail_cable, fail_at_fraction, namespace, bag, hardware. `graph_form:=composed`
starts the control loop's nodes in one process (composed_loop), each under its own name.
The run is settled once, as cdpr-graph settles it, and every node gets the same
parameters; `hardware:=true` leaves the plant simulator out for a bridge to take its
place. A simulated run ends with the plant; with a bag, once every node has exited, launch
prints how the run went (failure, detection, the cable named, recovery, KPIs: what
`make demo` prints) and where the bag is. On Ctrl-C a node gets cdpr-graph's grace
(drain, acknowledgements, DDS teardown) before launch escalates to SIGTERM.
"""
import os

from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler,
                            SetEnvironmentVariable)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from cdpr_bringup.graph.launch_files import (SIGTERM_TIMEOUT_S, dds_environment, graph_from_launch,
                                             launch_arguments, launch_parameters)
from cdpr_bringup.reports.summary import bag_summary


def graph(context):
    values = {argument.name: LaunchConfiguration(argument.name).perform(context)
              for argument in launch_arguments()}
    launched = graph_from_launch(values)
    specs, namespace = launched.specs, launched.namespace
    # a composed process runs several nodes, each named by its own class: no name remap
    nodes = {spec.name: Node(package=spec.package, executable=spec.executable,
                             name=None if spec.members else spec.name, namespace=namespace,
                             arguments=spec.arguments(), parameters=[launch_parameters(spec)],
                             output='screen', sigterm_timeout=str(SIGTERM_TIMEOUT_S))
             for spec in specs}
    actions = list(nodes.values())
    if launched.simulated:
        plant = next(spec.name for spec in specs if 'plant_simulator' in spec.node_names)
        actions.append(RegisterEventHandler(OnProcessExit(
            target_action=nodes[plant],
            on_exit=[EmitEvent(event=Shutdown(reason='the run is complete'))])))
        if launched.bag:
            running = set(nodes.values())

            def summary_once_all_exited(event, _context):
                running.discard(event.action)
                if not running:
                    print('\n'.join(bag_summary(launched.bag, launched.settings, launched.namespace)),
                          flush=True)

            actions.append(RegisterEventHandler(OnProcessExit(on_exit=summary_once_all_exited)))
    return actions


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(argument.name, default_value=argument.default,
                               description=argument.description) for argument in launch_arguments()]
        + [SetEnvironmentVariable(name, value) for name, value in dds_environment(dict(os.environ)).items()]
        + [OpaqueFunction(function=graph)])
