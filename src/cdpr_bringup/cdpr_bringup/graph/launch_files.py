"""The launch files' side of cdpr-graph: their arguments are cdpr-graph's options, and
they start the very nodes, with the very parameters, cdpr-graph would.

Imports nothing of `launch`, which is not on PyPI: the launch files in launch/ turn these
plain values into launch actions.
"""
from __future__ import annotations

import argparse
import atexit
import os
import tempfile
from dataclasses import dataclass

import yaml

from cdpr_control.config import Section
from cdpr_msgs_py.dds import shipped_environment

from .launcher import STOP_GRACE_S, NodeSpec, parser, requested_graph

TRUE = ('true', '1', 'yes')
# How long launch waits after SIGINT before SIGTERM (its own default, 5 s, is shorter than
# a node's shutdown, runtime.spin.SHUTDOWN_LIMIT_S): cdpr-graph's grace, so that both stop
# the graph by the same signal sequence.
SIGTERM_TIMEOUT_S = STOP_GRACE_S


@dataclass(frozen=True)
class LaunchArgument:
    name: str
    default: str
    description: str


def launch_arguments() -> list[LaunchArgument]:
    """One launch argument per cdpr-graph option, named as its destination (`fail_cable`
    for --fail-cable); an empty value leaves the option out, a list is comma-separated (and
    the values of one --push space-separated: push:='2 0.3 0 0 20, 5 0.2 10 0 0')."""
    arguments = []
    for action in parser()._actions:
        if not action.option_strings or action.dest == 'help':
            continue
        if isinstance(action, argparse._StoreTrueAction):
            default = 'false'
        elif isinstance(action.default, list) or action.default is None:
            default = ''
        else:
            default = str(action.default)
        arguments.append(LaunchArgument(action.dest, default, action.help or action.dest))
    return arguments


def command_line(values: dict[str, str]) -> list[str]:
    """cdpr-graph's command line for launch argument `values` (strings, as launch has them)."""
    argv = []
    for action in parser()._actions:
        value = values.get(action.dest, '').strip()
        if not action.option_strings or action.dest == 'help' or not value:
            continue
        flag = action.option_strings[0]
        if isinstance(action, argparse._StoreTrueAction):
            argv += [flag] if value.lower() in TRUE else []
        elif isinstance(action, argparse._AppendAction):
            # an option of several values (--push) takes them space-separated
            argv += [part for item in value.split(',') if item.strip()
                     for part in (flag, *item.split())]
        else:
            argv += [flag, value]
    return argv


@dataclass(frozen=True)
class LaunchedGraph:
    """What the launch files start for their arguments: the nodes cdpr-graph would start,
    their namespace, whether the plant simulator is among them (the run ends when it
    does), the bag they record (None: none) and the run as settled."""

    specs: list[NodeSpec]
    namespace: str
    simulated: bool
    bag: str | None
    settings: Section


def graph_from_launch(values: dict[str, str]) -> LaunchedGraph:
    args = parser().parse_args(command_line(values))
    specs, settings = requested_graph(args)
    return LaunchedGraph(specs, args.namespace, not args.hardware, args.bag, settings)


def launch_parameters(spec: NodeSpec):
    """The `parameters` of the launch_ros Node starting `spec`: a node's own as a dict;
    for a composed process, a parameters file holding each of its nodes' under its name
    (removed when the launch ends)."""
    if not spec.members:
        return spec.parameters
    descriptor, path = tempfile.mkstemp(prefix='cdpr-launch-', suffix='.yaml')
    with os.fdopen(descriptor, 'w') as file:
        yaml.safe_dump(spec.parameters_document(), file)
    atexit.register(os.remove, path)
    return path


def dds_environment(environment: dict[str, str]) -> dict[str, str]:
    """What the launch files set in the nodes' environment: the shipped DDS set-up
    (cdpr_msgs_py/dds.py), unless the user has a Fast DDS profile of their own."""
    return {key: value for key, value in shipped_environment(environment).items()
            if environment.get(key) != value}
