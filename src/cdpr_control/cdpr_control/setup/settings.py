"""A settled run as ROS parameters, and back: values, never recipes.

The launcher settles a run once (cdpr_bringup.runs.settle): every section of the robot
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

from cdpr_msgs_py.contract import SETTINGS_OF, SETTINGS_OF_EVERY_NODE
from cdpr_msgs_py.stamps import seconds_to_ns

from cdpr_control.config import Section, default_descriptions, load_config, paper_defaults
from cdpr_control.model.robot import Robot
from cdpr_control.setup.robot_file import robot_from_section

ROBOT_DESCRIPTION = 'robot_description'
# Settled keys the defaults cannot list: a run's own, a motion's by its type, a safe point
# per cable, the Coulomb friction settled from the robot, the plant and the calibration,
# and the drives' delay settled from fdi.drive_delay_s. Any other name a node is given
# that its defaults lack is a misspelling, which the node reports as ignored.
OPEN_KEYS = ('run.', 'motion.', 'recovery.safe_points_m.', 'control.coulomb_friction_nm',
             'control.drive_delay_s')


def flatten(mapping: Mapping, prefix: str = '') -> dict[str, Any]:
    """Dotted names → values, as ROS parameters hold a mapping. An empty list or mapping
    is left out: ROS cannot type an empty array, and every reader has it as its default."""
    values = {}
    for key, value in mapping.items():
        name = f'{prefix}.{key}' if prefix else str(key)
        if isinstance(value, Mapping):
            values.update(flatten(value, name))
        elif isinstance(value, (list, tuple)):
            # a ROS array has one type: numbers written 1 and 1.5 in YAML are all floats
            if any(isinstance(item, float) for item in value):
                value = [float(item) if isinstance(item, int) and not isinstance(item, bool) else item
                         for item in value]
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
    return yaml.safe_dump({'robot': dict(robot)}, sort_keys=False, default_flow_style=None)


class Settings:
    """What a node is settled with: the robot and its sections (cdpr_control.config.Section),
    and those sections' values by dotted name."""

    def __init__(self, document: Section, values: Mapping[str, Any]):
        self.document = document
        self.values = dict(values)

    def declare(self, node) -> None:
        """Each value as a ROS parameter of `node` (a cdpr_msgs_py.runtime.node.CdprNode),
        described as the defaults files describe it, with the bounds the node's loaders
        checked it against (so once the node has built its core from these settings), and
        read-only but CdprNode.CHANGEABLE_SETTINGS."""
        descriptions = default_descriptions()
        defaults = flatten(paper_defaults())
        for key, value in self.values.items():
            bounds = self.document.bounds.get(key)
            described = descriptions.get(key) or f'see cdpr_control/defaults/{key.split(".")[0]}.yaml'
            if key in defaults and defaults[key] != value:
                # the defaults file's words are of its value; say that this is another
                described += (f' [so reads the default, {defaults[key]!r}; this run has {value!r}, '
                              f'from its set-up or calibration]')
            node.parameter(
                key, value, described,
                read_only=key not in node.CHANGEABLE_SETTINGS,
                value_range=(bounds.low, bounds.high) if bounds else None,
                constraints=bounds.text() if bounds else '')

    @property
    def robot(self) -> Robot:
        if not self.document.has('robot'):
            raise self.document.error(ROBOT_DESCRIPTION, (
                'is not given: start the node with a run\'s settled parameters (cdpr-graph, '
                'cdpr-scenario) or with config_file:=PATH of a robot file'))
        return robot_from_section(self.document.section('robot'))

    @property
    def period_s(self) -> float:
        """The control period (s)."""
        return self.document.section('control').number('period_s', positive=True)

    @property
    def period_ns(self) -> int:
        return seconds_to_ns(self.period_s)

    def section(self, name: str, default: Any = ...) -> Section:
        return self.document.section(name, default)

    def has(self, name: str) -> bool:
        return self.document.has(name)


def node_settings(node, name: str) -> Settings:
    """The settings `node` (a cdpr_msgs_py.runtime.node.CdprNode, the contract's node `name`)
    runs with, each key of its sections (contract.SETTINGS_OF): the values it was given (a
    launcher's settled run), else those of the robot file its `config_file` parameter
    names, else the paper's. The node is configured from them (its writers' history, its
    /diagnostics limits: CdprNode.configure); once it has built its core from them,
    `Settings.declare` makes them its ROS parameters."""
    sections = SETTINGS_OF[name] + SETTINGS_OF_EVERY_NODE
    source = f'parameters of {node.get_fully_qualified_name()}'
    text = node.parameter(ROBOT_DESCRIPTION, '', "the robot, as a robot file's YAML text (as ROS "
                          "passes a URDF); empty: config_file's")
    path = node.parameter('config_file', '', 'a robot file or set-up (path), read when no '
                          'robot_description is given')
    if text:
        base = Section(dict(paper_defaults(), robot=described_robot(text, source)), source)
    else:
        base = load_config(path) if path else Section(paper_defaults(), source)
    given = {key: value for key, value in node.given_parameters().items()
             if key.split('.')[0] in sections and key.startswith(OPEN_KEYS)}
    defaults = flatten({name: base.data[name] for name in sections if base.has(name)})
    # a key the defaults do not have (a safe point per cable, the run's failures) is typed
    # as given
    values = {key: node.given_value(key, defaults[key] if key in defaults else given[key])
              for key in list(defaults) + [key for key in given if key not in defaults]}
    # a section whose every value was left out (an empty list) is still there, so that its
    # reader names the key it misses
    document = {name: {} for name in sections if base.has(name)} | unflatten(values)
    if base.has('robot'):
        document['robot'] = base.data['robot']
    settings = Settings(Section(document, source if text or not path else f'{path} (and the {source})',
                                defaulted=base.defaulted, sources=base.sources), values)
    node.configure(settings, settings.period_s)
    return settings


def described_robot(text: str, source: str) -> dict:
    """The `robot` mapping of a robot_description parameter's YAML text."""
    try:
        described = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise Section({}, source).error(ROBOT_DESCRIPTION, f'is not valid YAML: {err}') from err
    if not isinstance(described, dict) or 'robot' not in described:
        raise Section({}, source).error(ROBOT_DESCRIPTION, 'must hold a YAML mapping with `robot:`')
    return described['robot']
