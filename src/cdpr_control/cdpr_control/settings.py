"""A settled run as ROS parameters, and back: values, never recipes.

The launcher settles a run once (cdpr_bringup.scenario_setup): every section of the robot
file (or set-up) filled in from the defaults, the calibration's thresholds merged, the command line
applied, the motion resolved and the failures placed at absolute times on 0-based cables.
Each node gets the sections it reads as dotted parameters (`fdi.epsilon_nm`,
`recovery.safe_points_m.4`, ...) and the robot as `robot_description`, a YAML text as
ROS passes a URDF; it builds its core from those values and opens no file.

A node started without them (`ros2 run` with only `config_file:=PATH`) reads that robot
file, with the paper's settings for what it leaves out; with neither, it has the paper's
settings and no robot (enough for the bag recorder).
"""
from __future__ import annotations

from typing import Any, Mapping

import yaml

from .config import Section, load_config, paper_defaults
from .robot import Robot, robot_from_section

ROBOT_DESCRIPTION = 'robot_description'
# The sections a settled run has besides `robot`, in the order docs/design.md §6 lists them.
SECTIONS = ('control', 'twin', 'plant', 'fdi', 'recovery', 'scheduling', 'streams', 'health',
            'markers', 'motion', 'run')


def flatten(mapping: Mapping, prefix: str = '') -> dict[str, Any]:
    """Dotted names → values, as ROS parameters hold a mapping. An empty list or mapping
    is left out: ROS cannot type an empty array, and every reader has it as its default."""
    values = {}
    for key, value in mapping.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        if isinstance(value, Mapping):
            values.update(flatten(value, name))
        elif isinstance(value, (list, tuple)):
            if value:
                values[name] = list(value)
        else:
            values[name] = value
    return values


def unflatten(values: Mapping[str, Any]) -> dict:
    """The mapping `flatten` made `values` from."""
    mapping: dict = {}
    for name, value in values.items():
        *outer, last = name.split('.')
        inner = mapping
        for key in outer:
            inner = inner.setdefault(key, {})
        inner[last] = value
    return mapping


def robot_description(robot: Mapping) -> str:
    """The `robot` section as the robot_description parameter's YAML text."""
    return yaml.safe_dump({'robot': dict(robot)}, sort_keys=False)


class Settings:
    """What a node is settled with: the robot and its sections (cdpr_control.config.Section)."""

    def __init__(self, document: Section):
        self.document = document

    @property
    def robot(self) -> Robot:
        if not self.document.has('robot'):
            raise self.document.error(ROBOT_DESCRIPTION, (
                'is not given: start the node with a run\'s settled parameters (cdpr-graph, '
                'cdpr-scenario) or with config_file:=PATH of a robot file'))
        return robot_from_section(self.document.section('robot'))

    def section(self, name: str, default: Any = ...) -> Section:
        return self.document.section(name, default)

    def has(self, name: str) -> bool:
        return self.document.has(name)


def node_settings(node) -> Settings:
    """The settings `node` (an rclpy Node whose parameters were declared from its
    overrides) was started with: the launcher's settled values, else those of the robot
    file its `config_file` parameter names (a path)."""
    given = node.get_parameters_by_prefix('')
    source = f'parameters of {node.get_fully_qualified_name()}'
    if ROBOT_DESCRIPTION not in given:
        path = node.parameter('config_file', '')
        return Settings(load_config(path) if path else Section(paper_defaults(), source))
    try:
        described = yaml.safe_load(given[ROBOT_DESCRIPTION].value)
    except yaml.YAMLError as err:
        raise Section({}, source).error(ROBOT_DESCRIPTION, f'is not valid YAML: {err}') from err
    if not isinstance(described, dict) or 'robot' not in described:
        raise Section({}, source).error(ROBOT_DESCRIPTION, 'must hold a YAML mapping with `robot:`')
    document = unflatten({name: parameter.value for name, parameter in given.items()
                          if name.split('.')[0] in SECTIONS})
    document['robot'] = described['robot']
    return Settings(Section(document, source))
