"""The topic contract of docs/design.md §3: names (relative to the namespace), the one
table of topics — type, QoS, writer and readers of each — and the modes.

Imported by the core, which runs without ROS: message types are 'package/msg/Name'
strings here, resolved by message_class() only where a node needs the class.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass
from enum import Enum

DEFAULT_NAMESPACE = '/cdpr'

JOINT_STATES = 'joint_states'
REFERENCE = 'reference'
REFERENCE_POSE = 'reference/pose'
GOAL = 'goal'
EFFORT_COMMAND = 'effort_command'
TWIN_JOINT_STATES = 'twin/joint_states'
TWIN_POSE = 'twin/pose'
FDI_RESIDUAL = 'fdi/residual'
FDI_BROKEN_CABLE = 'fdi/broken_cable'
MODE = 'mode'
RECOVERY_TENSIONS = 'recovery/tensions'
RECOVERY_REFERENCE = 'recovery/reference'
GROUND_TRUTH_POSE = 'ground_truth/pose'
GROUND_TRUTH_TENSIONS = 'ground_truth/tensions'
INJECT_FAILURE = 'inject_failure'
MARKERS = 'markers'
CLOCK = '/clock'
RECORDER_PROGRESS = 'bag_recorder/progress'
DIAGNOSTICS = '/diagnostics'
# The plant simulator's /diagnostics key: {cable (1-based): instant it really parted (s)}
# as JSON, ground truth for a run's failure_time_s.
BROKEN_AT_KEY = 'plant broken_at_s'
# The plant simulator's /diagnostics key: the true position (m) of the last state it
# published, as JSON: where the run ended, whatever a recorder kept.
LAST_TRUE_POSITION_KEY = 'plant last true position m'

# The nodes of the graph, by executable. A hardware bridge takes the plant simulator's
# place on its topics (docs/hardware.md).
TRAJECTORY_GENERATOR = 'trajectory_generator'
CONTROLLER = 'controller'
DIGITAL_TWIN = 'digital_twin'
SUPERVISOR = 'supervisor'
PLANT_SIMULATOR = 'plant_simulator'
BAG_RECORDER = 'bag_recorder'
MARKERS_NODE = 'markers'
# A hardware bridge in the plant simulator's place, for a ros2_control robot.
ROS2_CONTROL_BRIDGE = 'ros2_control_bridge'

# The sections of a settled run (cdpr_control.settings) each node reads as its ROS
# parameters, besides those every node reads.
SETTINGS_OF = {
    TRAJECTORY_GENERATOR: ('control', 'motion'),
    CONTROLLER: ('control',),
    DIGITAL_TWIN: ('control', 'twin'),
    SUPERVISOR: ('control', 'fdi', 'recovery'),
    PLANT_SIMULATOR: ('control', 'plant', 'run'),
    BAG_RECORDER: ('control',),
    MARKERS_NODE: ('control', 'fdi', 'recovery', 'markers'),
    ROS2_CONTROL_BRIDGE: ('control', 'plant'),
}
SETTINGS_OF_EVERY_NODE = ('streams', 'health')


class Delivery(Enum):
    """The QoS kind of a topic; cdpr_msgs_py.qos holds the profile of each."""
    STREAM = 'per-cycle stream'
    # Verdicts and modes: a reader that joins late still gets the last value.
    LATCHED = 'latched'
    DIAGNOSTICS = 'diagnostics'
    # Drawn for a viewer a few times a second: a reader that lags loses old frames only.
    DISPLAY = 'display'


@dataclass(frozen=True)
class Reader:
    """A node that subscribes to a topic.

    `tick`: the message that drives the node, subscribed to only once its other endpoints
    have matched (CdprNode.start_when_matched), so its start cannot wait for that one.
    `pacing`: the node waits for this topic before each answer, which it does only in
    lockstep and only when told the writer is there (the controller's
    `wait_for_supervisor`); in realtime the wait would cost a third of the loop.
    `simulated`: read by the plant simulator only, not by a hardware bridge in its place.
    `lockstep`: read in lockstep only (the plant learns from the residual which tick a
    mode applies to, for a run that ends at the engine's tick; in realtime it takes its
    own tick, and the delivery would cost ~5 % of a core).
    `display`: read to draw it (the markers node): the reader subscribes at once, and no
    writer waits for it (the start handshake leaves it out), so that it never holds up
    the loop.
    """
    node: str
    tick: bool = False
    pacing: bool = False
    simulated: bool = False
    display: bool = False
    lockstep: bool = False


@dataclass(frozen=True)
class Topic:
    """One topic of the contract. `writer` is None for a topic no node of the graph owns:
    anyone may write it, or every node does (/diagnostics). `every_tick`: written from the
    first tick on, so the start handshake has its readers matched before the plant starts
    (graph.graph_nodes); the rest need none: a latched topic reaches late readers, and the
    others are written on demand or only in a recovery, long after every reader matched.
    `lockstep`: written in lockstep only. `simulated`: written by the plant simulator
    only, never by a hardware bridge in its place (the truth, the simulated clock)."""
    name: str
    type: str
    delivery: Delivery
    writer: str | None
    readers: tuple[Reader, ...]
    every_tick: bool = False
    lockstep: bool = False
    simulated: bool = False

    @property
    def on_demand(self) -> bool:
        """Written at every tick but read by no node of the loop, only by the recorder or
        a display: its writer builds and publishes it only while it has a reader
        (GuardedPublisher.publish_if_subscribed). It keeps its place in the start
        handshake, so a recording has it from the first tick."""
        return self.every_tick and all(reader.node == BAG_RECORDER or reader.display
                                       for reader in self.readers)


# The recorder reads every topic; like the loop's nodes it is driven by joint_states.
_RECORDER = Reader(BAG_RECORDER)
_MARKERS = Reader(MARKERS_NODE, display=True)
_STREAM, _LATCHED = Delivery.STREAM, Delivery.LATCHED

TOPICS = {topic.name: topic for topic in (
    Topic(JOINT_STATES, 'sensor_msgs/msg/JointState', _STREAM, PLANT_SIMULATOR,
          (Reader(TRAJECTORY_GENERATOR, tick=True), Reader(CONTROLLER, tick=True),
           Reader(SUPERVISOR, tick=True), Reader(BAG_RECORDER, tick=True), _MARKERS),
          every_tick=True),
    Topic(REFERENCE, 'sensor_msgs/msg/JointState', _STREAM, TRAJECTORY_GENERATOR,
          (Reader(CONTROLLER), Reader(DIGITAL_TWIN, tick=True), Reader(SUPERVISOR), _RECORDER),
          every_tick=True),
    Topic(REFERENCE_POSE, 'geometry_msgs/msg/PoseStamped', _STREAM, TRAJECTORY_GENERATOR,
          (_RECORDER,), every_tick=True),
    Topic(GOAL, 'geometry_msgs/msg/PointStamped', _STREAM, None,
          (Reader(TRAJECTORY_GENERATOR), _RECORDER)),
    Topic(EFFORT_COMMAND, 'sensor_msgs/msg/JointState', _STREAM, CONTROLLER,
          (Reader(PLANT_SIMULATOR), Reader(SUPERVISOR), _RECORDER), every_tick=True),
    Topic(TWIN_JOINT_STATES, 'sensor_msgs/msg/JointState', _STREAM, DIGITAL_TWIN,
          (Reader(SUPERVISOR), _RECORDER), every_tick=True),
    Topic(TWIN_POSE, 'geometry_msgs/msg/PoseStamped', _STREAM, DIGITAL_TWIN,
          (_RECORDER, _MARKERS), every_tick=True),
    Topic(FDI_RESIDUAL, 'sensor_msgs/msg/JointState', _STREAM, SUPERVISOR,
          (Reader(CONTROLLER, pacing=True), Reader(PLANT_SIMULATOR, simulated=True, lockstep=True),
           _RECORDER),
          every_tick=True),
    Topic(FDI_BROKEN_CABLE, 'std_msgs/msg/Int32', _LATCHED, SUPERVISOR,
          (Reader(CONTROLLER), _RECORDER, _MARKERS)),
    Topic(MODE, 'std_msgs/msg/String', _LATCHED, SUPERVISOR,
          (Reader(CONTROLLER), Reader(PLANT_SIMULATOR), _RECORDER)),
    Topic(RECOVERY_TENSIONS, 'sensor_msgs/msg/JointState', _STREAM, SUPERVISOR,
          (Reader(CONTROLLER), _RECORDER)),
    Topic(RECOVERY_REFERENCE, 'sensor_msgs/msg/JointState', _STREAM, SUPERVISOR,
          (Reader(CONTROLLER), _RECORDER, _MARKERS)),
    # The truth, for evaluation: never read by control or FDI.
    Topic(GROUND_TRUTH_POSE, 'geometry_msgs/msg/PoseStamped', _STREAM, PLANT_SIMULATOR,
          (_RECORDER,), every_tick=True, simulated=True),
    Topic(GROUND_TRUTH_TENSIONS, 'sensor_msgs/msg/JointState', _STREAM, PLANT_SIMULATOR,
          (_RECORDER,), every_tick=True, simulated=True),
    Topic(INJECT_FAILURE, 'std_msgs/msg/Int32', _STREAM, None,
          (Reader(PLANT_SIMULATOR), _RECORDER)),
    Topic(MARKERS, 'visualization_msgs/msg/MarkerArray', Delivery.DISPLAY, MARKERS_NODE,
          (_RECORDER,)),
    Topic(CLOCK, 'rosgraph_msgs/msg/Clock', _STREAM, PLANT_SIMULATOR,
          (_RECORDER,), every_tick=True, lockstep=True, simulated=True),
    Topic(DIAGNOSTICS, 'diagnostic_msgs/msg/DiagnosticArray', Delivery.DIAGNOSTICS, None,
          (_RECORDER,)),
    # The stamp of the newest tick the recorder has written: a plant told to wait for it
    # (`wait_for_recorder`) runs no further ahead of it in lockstep, and at the end of a
    # run in either mode waits until it has the last state, so that the bag gets every tick.
    Topic(RECORDER_PROGRESS, 'std_msgs/msg/Header', _LATCHED, BAG_RECORDER,
          (Reader(PLANT_SIMULATOR, simulated=True),)),
)}


def topics_read_by(node: str) -> list[Topic]:
    """The topics `node` subscribes to, in the table's order."""
    return [topic for topic in TOPICS.values() if any(reader.node == node for reader in topic.readers)]


def message_class(type_name: str):
    """The message class of a 'package/msg/Name' type (this imports its package)."""
    package, kind, name = type_name.split('/')
    return getattr(importlib.import_module(f'{package}.{kind}'), name)


# What the controller is doing, published on `mode` by the supervisor: the one
# definition of the mode names (the controller core and the health rules import them).
NOMINAL = 'NOMINAL'
RECOVERY_TENSION = 'RECOVERY_TENSION'
RECOVERY_MOVE = 'RECOVERY_MOVE'
SAFE_HOLD = 'SAFE_HOLD'
FAULT = 'FAULT'
MODES = (NOMINAL, RECOVERY_TENSION, RECOVERY_MOVE, SAFE_HOLD, FAULT)


# A ROS integer parameter is an int64: every integer setting must fit, and an integer
# range unbounded on a side ends there.
INT64_MIN, INT64_MAX = -2 ** 63, 2 ** 63 - 1


def joint_names(cable_count: int) -> list[str]:
    """motor_1 … motor_m, the joint order everywhere."""
    return [f'motor_{i + 1}' for i in range(cable_count)]
