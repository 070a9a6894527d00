"""The whole cdpr graph, as `cdpr-graph` starts it: `ros2 launch cdpr_bringup cdpr.launch.py`.

Arguments are cdpr-graph's options (`ros2 launch cdpr_bringup cdpr.launch.py --show-args`):
config (robot file or set-up), motions, motion, fidelity, clock, detector, calibration,
fail_cable, fail_at_fraction, namespace, bag, hardware. The run is settled once, as
cdpr-graph settles it, and every node gets the same parameters; `hardware:=true` leaves the
plant simulator out for a bridge to take its place. A simulated run ends with the plant.
"""
import os

from launch import LaunchDescription
from launch.actions import (DeclareLaunchArgument, EmitEvent, OpaqueFunction, RegisterEventHandler,
                            SetEnvironmentVariable)
from launch.event_handlers import OnProcessExit
from launch.events import Shutdown
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node

from cdpr_bringup.launching import dds_environment, graph_from_launch, launch_arguments


def graph(context):
    values = {argument.name: LaunchConfiguration(argument.name).perform(context)
              for argument in launch_arguments()}
    specs, namespace, simulated = graph_from_launch(values)
    nodes = {spec.name: Node(package=spec.package, executable=spec.executable, name=spec.name,
                             namespace=namespace, parameters=[spec.parameters], output='screen')
             for spec in specs}
    actions = list(nodes.values())
    if simulated:
        actions.append(RegisterEventHandler(OnProcessExit(
            target_action=nodes['plant_simulator'],
            on_exit=[EmitEvent(event=Shutdown(reason='the run is complete'))])))
    return actions


def generate_launch_description():
    return LaunchDescription(
        [DeclareLaunchArgument(argument.name, default_value=argument.default,
                               description=argument.description) for argument in launch_arguments()]
        + [SetEnvironmentVariable(name, value) for name, value in dds_environment(dict(os.environ)).items()]
        + [OpaqueFunction(function=graph)])
