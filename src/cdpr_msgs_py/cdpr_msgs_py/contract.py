"""The topic contract of docs/design.md §3: names (relative to the namespace), the one
table of topics — type, QoS, writer, readers and rate of each — the modes, and what a
tick delivers (design.md §3, "What a tick delivers"): loop topics every tick, view
topics at the view rate, events on change.

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
# The plant simulator's /diagnostics key: the figures of the end-effector from every tick
# (cdpr_twin.models.run_figures), as JSON: where the run ended among them, whatever a recorder kept.
RUN_FIGURES_KEY = 'plant run figures'

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

# The sections of a settled run (cdpr_control.setup.settings) each node reads as its ROS
# parameters, besides those every node reads.
SETTINGS_OF = {
    TRAJECTORY_GENERATOR: ('control', 'motion'),
    CONTROLLER: ('control',),
    DIGITAL_TWIN: ('control', 'twin'),
    SUPERVISOR: ('control', 'fdi', 'recovery', 'twin'),
    PLANT_SIMULATOR: ('control', 'plant', 'run', 'motion'),
    BAG_RECORDER: ('control',),
    MARKERS_NODE: ('control', 'fdi', 'recovery', 'markers', 'twin'),
    ROS2_CONTROL_BRIDGE: ('control', 'plant'),
}
SETTINGS_OF_EVERY_NODE = ('streams', 'health')


class Rate(Enum):
    """How often a topic is written."""
    # Control, FDI and the record need every tick: every bag holds every one.
    TICK = 'every tick'
    # For people and their tools (RViz, Foxglove, plots): on the view ticks only
    # (`streams.view_rate_hz`; ViewTicks), the same in both clock modes and both engines.
    VIEW = 'view rate'
    # Verdicts, modes, goals, injections, statuses: when there is something to say.
    CHANGE = 'on change'


# The verdict the supervisor gives on tick k (broken cables, mode, recovery setpoints),
# from the twin's and its own judgement of that tick, steers the loop from tick k + this
# on, in both engines alike: in lockstep the cycle's critical path is then plant →
# controller → plant, and the twin and the supervisor run beside it a tick behind.
VERDICT_DELAY_TICKS = 2


# The default of `streams.view_rate_hz` (defaults/streams.yaml).
VIEW_RATE_HZ = 50.0


class ViewTicks:
    """Which ticks are view ticks: every `every`-th from tick 0 (stamp 0), `every` =
    the loop rate over `view_rate_hz`, which must divide it; 0 Hz: every tick."""

    def __init__(self, view_rate_hz: float, period_s: float):
        if view_rate_hz == 0.0:
            self.every = 1
        else:
            ratio = 1.0 / (view_rate_hz * period_s)
            self.every = max(round(ratio), 1)
            if not (view_rate_hz > 0.0 and abs(ratio - self.every) < 1e-9 * ratio):
                raise ValueError(f'{view_rate_hz:g} Hz must divide the loop rate {1.0 / period_s:g} Hz '
                                 f'(or be 0: every tick)')
        self.period_ns = round(period_s * 1e9)

    @classmethod
    def of_streams(cls, streams, period_s: float) -> 'ViewTicks':
        """From the `streams` section (a cdpr_control.config.Section: this package reads no
        file); a rate that does not divide the loop's is the key's error."""
        rate = streams.number('view_rate_hz', VIEW_RATE_HZ, non_negative=True)
        try:
            return cls(rate, period_s)
        except ValueError as err:
            raise streams.error('view_rate_hz', str(err)) from None

    def at(self, stamp_ns: int) -> bool:
        """Whether the tick stamped `stamp_ns` is a view tick."""
        return (stamp_ns // self.period_ns) % self.every == 0


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
    anyone may write it, or every node does (/diagnostics). `rate`: how often it is
    written. `from_first_tick`: a loop or view topic, written from the first tick on, so
    the start handshake has its readers matched before the plant starts
    (graph.graph_nodes); the rest need none: a latched topic reaches late readers, and the
    others are written on demand or only in a recovery, long after every reader matched
    (`rate` TICK, `from_first_tick` False: recovery/*).
    `lockstep`: written in lockstep only. `simulated`: written by the plant simulator
    only, never by a hardware bridge in its place (the truth, the simulated clock)."""
    name: str
    type: str
    delivery: Delivery
    writer: str | None
    readers: tuple[Reader, ...]
    rate: Rate = Rate.CHANGE
    from_first_tick: bool = False
    lockstep: bool = False
    simulated: bool = False

    @property
    def on_demand(self) -> bool:
        """A view topic: read by no node of the loop, only by the recorder, a display or
        people's tools, so its writer builds and publishes it only while it has a reader
        (GuardedPublisher.publish_if_subscribed). It keeps its place in the start
        handshake, so a recording has it from the first tick."""
        return self.rate is Rate.VIEW


# The recorder reads every topic; like the loop's nodes it is driven by joint_states.
_RECORDER = Reader(BAG_RECORDER)
_MARKERS = Reader(MARKERS_NODE, display=True)
_STREAM, _LATCHED = Delivery.STREAM, Delivery.LATCHED
_LOOP = dict(rate=Rate.TICK, from_first_tick=True)
_VIEW = dict(rate=Rate.VIEW, from_first_tick=True)

TOPICS = {topic.name: topic for topic in (
    Topic(JOINT_STATES, 'sensor_msgs/msg/JointState', _STREAM, PLANT_SIMULATOR,
          (Reader(TRAJECTORY_GENERATOR, tick=True), Reader(CONTROLLER, tick=True),
           Reader(SUPERVISOR, tick=True), Reader(BAG_RECORDER, tick=True)),
          **_LOOP),
    Topic(REFERENCE, 'sensor_msgs/msg/JointState', _STREAM, TRAJECTORY_GENERATOR,
          (Reader(CONTROLLER), Reader(DIGITAL_TWIN, tick=True), Reader(SUPERVISOR), _RECORDER),
          **_LOOP),
    Topic(REFERENCE_POSE, 'geometry_msgs/msg/PoseStamped', _STREAM, TRAJECTORY_GENERATOR,
          (_RECORDER, _MARKERS), **_VIEW),
    # The plant's figures count the tracking error of the settled motion only (run_figures).
    Topic(GOAL, 'geometry_msgs/msg/PointStamped', _STREAM, None,
          (Reader(TRAJECTORY_GENERATOR), Reader(PLANT_SIMULATOR, simulated=True), _RECORDER)),
    Topic(EFFORT_COMMAND, 'sensor_msgs/msg/JointState', _STREAM, CONTROLLER,
          (Reader(PLANT_SIMULATOR), Reader(SUPERVISOR), _RECORDER), **_LOOP),
    Topic(TWIN_JOINT_STATES, 'sensor_msgs/msg/JointState', _STREAM, DIGITAL_TWIN,
          (Reader(SUPERVISOR), _RECORDER), **_LOOP),
    Topic(TWIN_POSE, 'geometry_msgs/msg/PoseStamped', _STREAM, DIGITAL_TWIN,
          (_RECORDER, _MARKERS), **_VIEW),
    Topic(FDI_RESIDUAL, 'sensor_msgs/msg/JointState', _STREAM, SUPERVISOR,
          (Reader(CONTROLLER, pacing=True), Reader(PLANT_SIMULATOR, simulated=True, lockstep=True),
           _RECORDER),
          **_LOOP),
    Topic(FDI_BROKEN_CABLE, 'std_msgs/msg/Int32', _LATCHED, SUPERVISOR,
          (Reader(CONTROLLER), Reader(PLANT_SIMULATOR, simulated=True), _RECORDER, _MARKERS)),
    Topic(MODE, 'std_msgs/msg/String', _LATCHED, SUPERVISOR,
          (Reader(CONTROLLER), Reader(PLANT_SIMULATOR), _RECORDER)),
    # Every tick while a recovery runs.
    Topic(RECOVERY_TENSIONS, 'sensor_msgs/msg/JointState', _STREAM, SUPERVISOR,
          (Reader(CONTROLLER), _RECORDER), rate=Rate.TICK),
    Topic(RECOVERY_REFERENCE, 'sensor_msgs/msg/JointState', _STREAM, SUPERVISOR,
          (Reader(CONTROLLER), _RECORDER), rate=Rate.TICK),
    # The truth, for evaluation: never read by control or FDI.
    Topic(GROUND_TRUTH_POSE, 'geometry_msgs/msg/PoseStamped', _STREAM, PLANT_SIMULATOR,
          (_RECORDER, _MARKERS), **_VIEW, simulated=True),
    Topic(GROUND_TRUTH_TENSIONS, 'sensor_msgs/msg/JointState', _STREAM, PLANT_SIMULATOR,
          (_RECORDER, _MARKERS), **_VIEW, simulated=True),
    Topic(INJECT_FAILURE, 'std_msgs/msg/Int32', _STREAM, None,
          (Reader(PLANT_SIMULATOR), _RECORDER)),
    # A frame per view tick, drawn from the view topics.
    Topic(MARKERS, 'visualization_msgs/msg/MarkerArray', Delivery.DISPLAY, MARKERS_NODE,
          (_RECORDER,), rate=Rate.VIEW),
    # Simulated time, for viewers started with use_sim_time (no node of the graph reads it).
    Topic(CLOCK, 'rosgraph_msgs/msg/Clock', _STREAM, PLANT_SIMULATOR,
          (_RECORDER,), **_VIEW, lockstep=True, simulated=True),
    Topic(DIAGNOSTICS, 'diagnostic_msgs/msg/DiagnosticArray', Delivery.DIAGNOSTICS, None,
          (_RECORDER,)),
    # The stamp of the newest tick the recorder has written: a plant told to wait for it
    # (`wait_for_recorder`) runs no further ahead of it in lockstep, and at the end of a
    # run in either mode waits until it has the last state, so that the bag gets every tick.
    Topic(RECORDER_PROGRESS, 'std_msgs/msg/Header', _LATCHED, BAG_RECORDER,
          (Reader(PLANT_SIMULATOR, simulated=True),)),
)}


def raw_stream(topic: str) -> bool:
    """Whether `topic` is one of the contract's JointState streams, which the graph's nodes
    publish and take as CDR bytes (cdr.JointStateCodec): no message object is built on
    either side, ~50 µs of CPU less a delivery here (docs/performance.md)."""
    known = TOPICS.get(topic)
    return (known is not None and known.delivery is Delivery.STREAM
            and known.type == 'sensor_msgs/msg/JointState')


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
