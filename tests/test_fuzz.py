"""Property-based tests (hypothesis) for issue 6: bad input never reaches a motor.

Every message handler of every node is called directly, in this process, with random
messages: joint names right, reordered, missing, extra or unknown; arrays of any length
holding NaN, ±inf or huge values; stamps going backwards, repeating or jumping; any Int32,
any text, any point. No handler may raise; a message the contract calls invalid is
counted on its topic and changes nothing; nothing non-finite or beyond the torque limit
leaves the controller on effort_command or reaches the plant's motors. The config loaders
get every key of paper_robot.yaml deleted, of the wrong kind, out of its range and in it,
and random mutations: each loads it or raises a ConfigError that names the file and the
key, as the hand-written table tests/config_keys.yaml says they must.

A few inputs are kept out of the strategies: each restriction says why where it is made,
and tests/test_watchdogs.py covers what lies beyond it.
"""
from __future__ import annotations

import copy
import dataclasses
import math
import os
import re
from collections import Counter, defaultdict
from contextlib import contextmanager
from functools import reduce
from operator import getitem
from pathlib import Path

import numpy as np
import pytest
import rclpy
import rclpy.node
import yaml
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st
from std_msgs.msg import Int32, String

import cdpr_control.config
import cdpr_fdi.settings.config
from cdpr_bringup.runs.settle import realtime_scheduling
from cdpr_control.config import ConfigError, load_config, load_section, load_yaml, paper_defaults
from cdpr_control.control.controller import PdGains
from cdpr_control.control.controller_node import ControllerNode
from cdpr_control.model.friction import FrictionModel
from cdpr_control.point_mass.kinematics import inverse_kinematics
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.tension_distribution import configured_tension_distribution
from cdpr_control.control.trajectory_generator_node import TrajectoryGeneratorNode
from cdpr_fdi.settings.config import load_fdi_config, load_recovery_config
from cdpr_fdi.view.markers import MarkerStyle
from cdpr_fdi.nodes.supervisor_node import SupervisorNode
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import joint_state, ns_to_stamp, point_stamped, stamp_to_ns
from cdpr_msgs_py.stamps import NANOSECONDS
from cdpr_msgs_py.health import HealthLimits
from cdpr_twin.nodes.digital_twin_node import DigitalTwinNode
from cdpr_twin.models.plant import PlantConfig
from cdpr_twin.nodes.plant_simulator_node import PlantSimulatorNode
from conftest import MOTIONS, PAPER_ROBOT, kept

ROBOT = load_robot(PAPER_ROBOT)
CABLES = ROBOT.cable_count
NAMES = contract.joint_names(CABLES)
TORQUE_LIMIT_NM = ROBOT.motor.torque_limit_nm
CONTROL = load_section(PAPER_ROBOT, 'control')
PERIOD_NS = int(round(CONTROL.number('period_s') * 1e9))
LEAD_CYCLES = CONTROL.integer('reference_lead_cycles')
MODES = contract.MODES
ALL_FIELDS = ('position', 'velocity', 'effort')

# Examples per test as make test runs them, times CDPR_FUZZ_SCALE (1; docs/testing.md,
# "Fuzzing deeper"). 50 per message handler and mode: with 100, the handlers took 70 s of
# the suite's 600 s of test time, nearly all of it hypothesis drawing the messages.
SCALE = float(os.environ.get('CDPR_FUZZ_SCALE', '1'))


def examples(count: int) -> int:
    return max(1, round(count * SCALE))


FUZZ = settings(max_examples=examples(50), deadline=None, database=None,
                suppress_health_check=[HealthCheck.too_slow])

# Huge and garbage values overflow numpy inside the nodes' models (forward kinematics of
# a pose 1e300 away): expected here, and the handlers must cope, which the tests check.
pytestmark = pytest.mark.filterwarnings('ignore:overflow encountered:RuntimeWarning',
                                        'ignore:invalid value encountered:RuntimeWarning')


# ---- messages -------------------------------------------------------------------------

# Beyond about 1e306 the controller's PD terms overflow to inf − inf and it withholds the
# command (test_watchdogs); 1e300 still drives every torque far past the limit.
HUGE = 1e300
finite_values = st.floats(min_value=-HUGE, max_value=HUGE)
any_values = st.one_of(finite_values, st.sampled_from([math.nan, math.inf, -math.inf, HUGE, -HUGE]))


def value_lists(values):
    """Mostly one value per joint, sometimes any count."""
    return st.one_of(st.lists(values, min_size=CABLES, max_size=CABLES),
                     st.lists(values, max_size=CABLES + 2))


joint_name_lists = st.one_of(
    st.just(NAMES),
    st.permutations(NAMES),
    st.lists(st.sampled_from(NAMES + ['motor_0', f'motor_{CABLES + 1}', 'Motor_1', 'motor_01', '']),
             max_size=CABLES + 2),
    st.lists(st.text(max_size=12), max_size=CABLES + 2))

# Stamps in ns: on the ticks near the start of a run, or anywhere a
# builtin_interfaces/Time can point.
tick_stamps = st.integers(-3, 40).map(lambda tick: tick * PERIOD_NS)
any_stamps = st.builds(lambda sec, nanosec: sec * NANOSECONDS + nanosec,
                       st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(0, NANOSECONDS - 1))
some_stamps = st.one_of(tick_stamps, any_stamps)


def joint_states(stamps=some_stamps):
    """Any JointState, valid by accident at most."""
    return st.builds(joint_state, joint_name_lists, stamps, value_lists(any_values),
                     value_lists(any_values), value_lists(any_values))


def valid_joint_states(stamps=some_stamps, values=finite_values):
    exact = st.lists(values, min_size=CABLES, max_size=CABLES)
    return st.builds(joint_state, st.just(NAMES), stamps, exact, exact, exact)


def some_joint_states(stamps=some_stamps):
    """Valid ones and any."""
    return st.one_of(valid_joint_states(stamps), joint_states(stamps))


def on_ticks(callbacks, strays):
    """A run of ticks 0, 1, …; per tick a few `strays` (any handler, any stamp), then each
    of `callbacks` in a random order, given the valid message of the tick, any message,
    or nothing: (strays, order, [(on_tick, message) or None]). Without the ticks, inputs
    that a node pairs by stamp would almost never meet."""
    on_tick = valid_joint_states(st.just(0)).map(lambda message: (True, message))
    # mostly the valid message of the tick, so that all of a tick's inputs often arrive
    message = st.one_of(on_tick, on_tick, on_tick, st.none(),
                        joint_states().map(lambda message: (False, message)))
    tick = st.tuples(st.lists(strays, max_size=3), st.permutations(sorted(callbacks)),
                     st.lists(message, min_size=len(callbacks), max_size=len(callbacks)))
    return st.lists(tick, min_size=3, max_size=12)


def deliveries(ticks):
    """(callback, message) of `on_ticks` in delivery order, stamped with their tick."""
    for tick, (strays, order, messages) in enumerate(ticks):
        yield from strays
        for callback, item in zip(order, messages):
            if item is not None:
                on_tick, message = item
                if on_tick:
                    message.header.stamp = ns_to_stamp(tick * PERIOD_NS)
                yield callback, message


cable_messages = st.one_of(st.integers(-1, CABLES + 1), st.integers(-2 ** 31, 2 ** 31 - 1)).map(
    lambda number: Int32(data=number))
mode_messages = st.one_of(
    st.sampled_from(MODES),
    st.sampled_from([mode.lower() for mode in MODES] + [f' {MODES[0]}', f'{MODES[0]}\n', '']),
    st.text()).map(lambda text: String(data=text))


def well_formed(message, fields=ALL_FIELDS) -> bool:
    """The contract's rule, written out: names motor_1 … motor_m in that order and, in
    every field the handler uses, one finite value per joint."""
    return list(message.name) == NAMES and all(
        len(values) == CABLES and all(map(math.isfinite, values))
        for values in (getattr(message, field) for field in fields))


# ---- nodes in this process --------------------------------------------------------------

@pytest.fixture(scope='module', params=['lockstep', 'realtime'])
def clock_mode(request):
    """rclpy in this process; every node made in it runs in `clock_mode`, on the paper
    robot's file as a node started by hand does."""
    rclpy.init(args=['--ros-args', '-p', f'clock_mode:={request.param}', '-p', f'config_file:={PAPER_ROBOT}',
                     '-p', f'motions_file:={MOTIONS}'])
    yield request.param
    rclpy.shutdown()


@contextmanager
def parsing_once(parsed: dict):
    """Inside the block the config loaders parse each file once (into `parsed`): PyYAML's
    pure-Python parser is most of a node's construction, and every example needs a fresh
    node."""
    def load_once(path):
        if str(path) not in parsed:
            parsed[str(path)] = load_yaml(path)
        return copy.deepcopy(parsed[str(path)])

    with pytest.MonkeyPatch.context() as patch:
        for module in (cdpr_control.config, cdpr_fdi.settings.config):
            patch.setattr(module, 'load_yaml', load_once)
        yield


SHIPPED_CONFIGS: dict = {}


class Recorder:
    """Everything a node publishes, kept per topic instead of sent. It reads every topic,
    as a bag recorder would: the topics published only while read are published too."""

    def __init__(self, node):
        self.node = node
        self.messages = defaultdict(list)
        for publisher in node.publishers:
            publisher.publish = kept(self.messages[publisher.topic_name], publisher)
            publisher.get_subscription_count = lambda: 1

    def __getitem__(self, topic: str) -> list:
        return self.messages[self.node.resolve_topic_name(topic)]

    def total(self) -> int:
        return sum(map(len, self.messages.values()))


@contextmanager
def fresh(node_class):
    """A new node of `node_class` and the recorder of what it publishes."""
    with parsing_once(SHIPPED_CONFIGS):
        node = node_class()
    try:
        yield node, Recorder(node)
    finally:
        node.destroy_node()


def frozen(value):
    """`value` as nested tuples that compare by content (arrays bit for bit, NaN too)."""
    if isinstance(value, np.ndarray):
        return value.shape, value.tobytes()
    if dataclasses.is_dataclass(value):
        return tuple(frozen(getattr(value, field.name)) for field in dataclasses.fields(value))
    if isinstance(value, dict):
        return tuple((key, frozen(item)) for key, item in value.items())
    if isinstance(value, (list, tuple)):
        return tuple(frozen(item) for item in value)
    return value


def deliver(node, recorder, callback: str, message, topic: str, valid: bool, state) -> None:
    """Hand `message` to the node's `callback`. A valid one must not be counted as
    rejected; an invalid one must be counted once on `topic`, change nothing of `state`
    (a function of the node) and publish nothing."""
    rejected = Counter(node.diagnostics.rejected)
    before = state(node)
    published = recorder.total()
    getattr(node, callback)(message)
    if valid:
        assert node.diagnostics.rejected == rejected
        return
    rejected[topic] += 1
    assert node.diagnostics.rejected == rejected
    assert state(node) == before
    assert recorder.total() == published


def assert_safe_command(command, broken: set[int], answered_stamps: set[int]) -> None:
    """One finite torque per motor within the limit, zero on broken cables (0-based),
    stamped as a state the controller received."""
    effort = np.array(command.effort)
    assert list(command.name) == NAMES
    assert effort.shape == (CABLES,)
    assert np.all(np.isfinite(effort)), effort
    assert np.all(np.abs(effort) <= TORQUE_LIMIT_NM), effort
    assert np.all(effort[sorted(broken)] == 0.0), (effort, broken)
    assert stamp_to_ns(command.header.stamp) in answered_stamps


def assert_finite_joint_states(messages) -> None:
    for message in messages:
        assert list(message.name) == NAMES
        for field in ALL_FIELDS:
            assert all(map(math.isfinite, getattr(message, field))), message


# ---- controller -----------------------------------------------------------------------

CONTROLLER_JOINT_INPUTS = {  # callback: (topic, fields it uses)
    'on_state': (contract.JOINT_STATES, ('position', 'velocity')),
    'on_reference': (contract.REFERENCE, ALL_FIELDS),
    'on_recovery_reference': (contract.RECOVERY_REFERENCE, ALL_FIELDS),
    'on_tensions': (contract.RECOVERY_TENSIONS, ('effort',)),
    'on_residual': (contract.FDI_RESIDUAL, ('effort',)),
}
controller_strays = st.one_of(
    st.tuples(st.sampled_from(sorted(CONTROLLER_JOINT_INPUTS)), some_joint_states()),
    st.tuples(st.just('on_broken_cable'), cable_messages),
    st.tuples(st.just('on_mode'), mode_messages))


def controller_input(callback: str, message) -> tuple[str, bool]:
    """(topic, valid) of a message for the controller's `callback`."""
    if callback == 'on_broken_cable':
        return contract.FDI_BROKEN_CABLE, 0 <= message.data <= CABLES
    if callback == 'on_mode':
        return contract.MODE, message.data in MODES
    topic, fields = CONTROLLER_JOINT_INPUTS[callback]
    return topic, well_formed(message, fields)


def controller_state(node):
    """What a message may change: mode, broken cables, setpoints and pending work."""
    core = node.controller
    return frozen((core.mode, core.broken, core.tension_setpoint_n, core.hold, core.tracked,
                   dict(node.setpoints.references), dict(node.setpoints.recovery_references),
                   dict(node.setpoints.recovery_tensions), node.verdict_ns, node.first_state_ns,
                   node.pending, list(node.answered)))


@FUZZ
@given(ticks=on_ticks(CONTROLLER_JOINT_INPUTS, controller_strays))
def test_controller_rejects_bad_input_and_commands_only_safe_torques(clock_mode, ticks):
    with fresh(ControllerNode) as (node, published):
        commands = published[contract.EFFORT_COMMAND]
        broken: set[int] = set()
        answered_stamps: set[int] = set()
        broken_when_first_answered: dict[int, frozenset[int]] = {}
        for callback, message in deliveries(ticks):
            topic, valid = controller_input(callback, message)
            sent = len(commands)
            if callback == 'on_state' and valid:
                answered_stamps.add(stamp_to_ns(message.header.stamp))
            deliver(node, published, callback, message, topic, valid, controller_state)
            if callback == 'on_broken_cable' and valid and message.data:
                broken.add(message.data - 1)
            if callback == 'on_mode' and valid:
                assert node.controller.mode == message.data
            assert set(np.flatnonzero(node.controller.broken)) == broken
            # a message releases at most the one state waiting for it
            assert len(commands) - sent <= 1
            for command in commands[sent:]:
                # A state is answered again with the command it first got (the plant
                # resends a state whose answer was lost), even if a cable broke in
                # between (reported): zero torque is due on the cables broken by then.
                first = broken_when_first_answered.setdefault(
                    stamp_to_ns(command.header.stamp), frozenset(broken))
                assert_safe_command(command, first, answered_stamps)


joint_values = st.lists(finite_values, min_size=CABLES, max_size=CABLES)


@FUZZ
@given(mode=st.sampled_from(MODES), broken=st.sets(st.integers(1, CABLES), max_size=CABLES),
       stamp=tick_stamps, reference=st.tuples(joint_values, joint_values, joint_values),
       recovery_reference=st.tuples(joint_values, joint_values, joint_values),
       tensions=joint_values, state=st.tuples(joint_values, joint_values))
def test_controller_answers_a_valid_state_with_one_safe_command(
        clock_mode, mode, broken, stamp, reference, recovery_reference, tensions, state):
    """With the setpoint its mode needs at the state's stamp, every valid state gets one
    command, and the same state again gets the same command (the plant resends a state
    whose answer it did not get)."""
    with fresh(ControllerNode) as (node, published):
        for cable in sorted(broken):
            node.on_broken_cable(Int32(data=cable))
        node.on_mode(String(data=mode))
        node.on_reference(joint_state(NAMES, stamp, *reference))
        node.on_recovery_reference(joint_state(NAMES, stamp, *recovery_reference))
        node.on_tensions(joint_state(NAMES, stamp, effort=tensions))
        assert not published[contract.EFFORT_COMMAND]
        node.on_state(joint_state(NAMES, stamp, *state))
        node.on_state(joint_state(NAMES, stamp, *state))
        commands = published[contract.EFFORT_COMMAND]
        assert len(commands) == 2
        assert_safe_command(commands[0], {cable - 1 for cable in broken}, {stamp})
        assert list(commands[1].effort) == list(commands[0].effort)
        assert not node.diagnostics.rejected


# ---- plant simulator ------------------------------------------------------------------

# Stamps relative to the plant's current tick (ns).
RELATIVE_STAMPS = {'current': 0, 'previous': -PERIOD_NS, 'next': PERIOD_NS}


def plant_steps(clock_mode: str):
    """Commands stamped relative to the plant's tick or anywhere, failure injections,
    and (realtime) timer ticks."""
    steps = [st.tuples(st.just('on_command'), some_joint_states(st.just(0)),
                       st.one_of(st.sampled_from(sorted(RELATIVE_STAMPS)), any_stamps)),
             st.tuples(st.just('on_inject'), cable_messages, st.none())]
    if clock_mode == 'realtime':
        steps.append(st.tuples(st.just('tick'), st.none(), st.none()))
    return st.one_of(steps)


def plant_state(node):
    return frozen((node.command, node.plant.broken))


@FUZZ
@given(data=st.data())
def test_plant_rejects_bad_commands_and_applies_only_safe_torques(clock_mode, data):
    steps = data.draw(st.lists(plant_steps(clock_mode), min_size=1, max_size=30))
    with fresh(PlantSimulatorNode) as (node, published):
        states = published[contract.JOINT_STATES]
        applied = []
        model_step = node.plant.model.step

        def recording_step(torque_nm, period_s, **forces):
            applied.append(np.array(torque_nm, dtype=float))
            model_step(torque_nm, period_s, **forces)

        node.plant.model.step = recording_step
        if clock_mode == 'lockstep':
            # What the start handshake does once a controller listens: state of tick 0.
            node.started = True
            node.publish_state()
        for callback, message, stamp in steps:
            steps_before, states_before = len(applied), len(states)
            if callback == 'tick':
                node.realtime_step()
                assert len(applied) == steps_before + 1
                continue
            if callback == 'on_inject':
                valid = 1 <= message.data <= CABLES
                deliver(node, published, callback, message, contract.INJECT_FAILURE, valid, plant_state)
                if valid:
                    assert message.data - 1 in node.plant.broken
                continue
            current = stamp_to_ns(states[-1].header.stamp) if states else 0
            if isinstance(stamp, str):
                stamp = current + RELATIVE_STAMPS[stamp]
            message.header.stamp = ns_to_stamp(stamp)
            valid = well_formed(message, ('effort',))
            command_before = node.command.copy()
            deliver(node, published, callback, message, contract.EFFORT_COMMAND, valid, plant_state)
            if not valid:
                assert len(applied) == steps_before
                continue
            if clock_mode == 'realtime':
                # held until the next one, within the motors' limit (and reported so)
                np.testing.assert_array_equal(
                    node.command, np.clip(message.effort, -TORQUE_LIMIT_NM, TORQUE_LIMIT_NM))
                assert len(applied) == steps_before
            elif stamp == current:
                # lockstep: the command of the current tick steps the plant once, clipped
                assert len(applied) == steps_before + 1
                np.testing.assert_array_equal(
                    applied[-1], np.clip(message.effort, -TORQUE_LIMIT_NM, TORQUE_LIMIT_NM))
                assert len(states) == states_before + 1
                assert stamp_to_ns(states[-1].header.stamp) == current + PERIOD_NS
            else:
                # lockstep: a command for any other tick changes nothing
                assert len(applied) == steps_before
                np.testing.assert_array_equal(node.command, command_before)
        for torque in applied:
            assert torque.shape == (CABLES,)
            assert np.all(np.isfinite(torque)), torque
            assert np.all(np.abs(torque) <= TORQUE_LIMIT_NM), torque
        assert_finite_joint_states(states)


# ---- digital twin -----------------------------------------------------------------------

# A point the robot can hang at: the twin starts where its first reference puts it.
central_points = st.tuples(st.floats(0.4, 1.3), st.floats(0.4, 1.5), st.floats(0.8, 1.6))


def twin_state(node):
    model = node.twin.model
    return frozen((node.last_stamp_ns, model.angle_rad, model.angular_velocity_rad_s,
                   model.position_m))


# The twin's first reference is a consistent one: angles its forward kinematics can
# place (motor 1 alone paid out by 50 rad makes on_reference raise LinAlgError, angles of
# 1e160 make it publish NaN from then on; both reported). Its stamp may be before 0.
@FUZZ
@given(start=central_points, first_stamp=tick_stamps,
       steps=st.lists(some_joint_states(), max_size=30))
def test_digital_twin_rejects_bad_or_stale_references_and_stays_finite(
        clock_mode, start, first_stamp, steps):
    with fresh(DigitalTwinNode) as (node, published):
        node.on_reference(joint_state(NAMES, first_stamp, inverse_kinematics(ROBOT, np.array(start)),
                                      np.zeros(CABLES), np.zeros(CABLES)))
        twin_states = published[contract.TWIN_JOINT_STATES]
        poses = published[contract.TWIN_POSE]
        # the pose, a view topic, on the view ticks only
        viewed = lambda stamp: int(node.view_ticks.at(stamp))  # noqa: E731
        assert len(twin_states) == 1 and len(poses) == viewed(first_stamp)
        latest = first_stamp
        for message in steps:
            stamp = stamp_to_ns(message.header.stamp)
            # a reference not after the last one is rejected too, as the node documents
            valid = well_formed(message) and stamp > latest
            sent, posed = len(twin_states), len(poses)
            deliver(node, published, 'on_reference', message, contract.REFERENCE, valid, twin_state)
            if valid:
                latest = stamp
                assert len(twin_states) == sent + 1 and len(poses) == posed + viewed(stamp)
                assert stamp_to_ns(twin_states[-1].header.stamp) == stamp
                if viewed(stamp):
                    assert stamp_to_ns(poses[-1].header.stamp) == stamp
        assert_finite_joint_states(twin_states)
        for twin in twin_states:
            assert np.all(np.abs(twin.effort) <= TORQUE_LIMIT_NM)
        for pose in poses:
            position = pose.pose.position
            assert all(map(math.isfinite, (position.x, position.y, position.z)))
            assert pose.pose.orientation.w == 1.0   # a point mass: the identity


# ---- supervisor -----------------------------------------------------------------------

SUPERVISOR_INPUTS = {  # callback: (topic, fields it uses)
    'on_state': (contract.JOINT_STATES, ALL_FIELDS),
    'on_command': (contract.EFFORT_COMMAND, ('effort',)),
    'on_twin': (contract.TWIN_JOINT_STATES, ALL_FIELDS),
    'on_reference': (contract.REFERENCE, ALL_FIELDS),
}


def supervisor_state(node):
    core = node.supervisor
    return frozen((node.inputs, node.last_tick_ns, node.origin_ns, node.published_broken,
                   node.published_mode, core.mode, core.broken))


def assert_sane_verdicts(published) -> None:
    """Finite residuals and setpoints, one residual per judged tick in order, cable
    numbers and modes from the contract."""
    residuals = published[contract.FDI_RESIDUAL]
    assert_finite_joint_states(residuals)
    assert_finite_joint_states(published[contract.RECOVERY_TENSIONS])
    assert_finite_joint_states(published[contract.RECOVERY_REFERENCE])
    stamps = [stamp_to_ns(residual.header.stamp) for residual in residuals]
    assert stamps == sorted(set(stamps))
    assert all(1 <= message.data <= CABLES for message in published[contract.FDI_BROKEN_CABLE])
    assert all(message.data in MODES for message in published[contract.MODE])


supervisor_strays = st.tuples(st.sampled_from(sorted(SUPERVISOR_INPUTS)), some_joint_states())


@FUZZ
@given(ticks=on_ticks(SUPERVISOR_INPUTS, supervisor_strays))
def test_supervisor_rejects_bad_input_and_publishes_finite_verdicts(clock_mode, ticks):
    with fresh(SupervisorNode) as (node, published):
        for callback, message in deliveries(ticks):
            topic, fields = SUPERVISOR_INPUTS[callback]
            deliver(node, published, callback, message, topic, well_formed(message, fields),
                    supervisor_state)
        assert_sane_verdicts(published)


# Where the supervisor finds the end-effector, plausible or not: recovery must then plan
# from there or declare FAULT, never raise.
pose_angles = st.one_of(central_points.map(lambda point: inverse_kinematics(ROBOT, np.array(point))),
                        joint_values.map(np.array))


@settings(FUZZ, max_examples=examples(30))
@given(cable=st.integers(0, CABLES - 1), failure_tick=st.integers(1, 3), extra_ticks=st.integers(1, 6),
       angles=pose_angles, reference=st.tuples(joint_values, joint_values, joint_values))
def test_supervisor_names_a_freed_motor_whatever_the_pose(
        clock_mode, cable, failure_tick, extra_ticks, angles, reference):
    """A motor whose applied torque meets no load (zero torque, zero acceleration) and
    whose command exceeds the twin's is named at once; recovery starts or FAULT is
    declared, with finite setpoints."""
    holding = np.full(CABLES, -0.5)
    command = holding.copy()
    command[cable] = 0.0
    with fresh(SupervisorNode) as (node, published):
        for tick in range(failure_tick + extra_ticks):
            stamp = tick * PERIOD_NS
            # the drive applied the previous command, which never changes here
            node.on_state(joint_state(NAMES, stamp, angles, np.zeros(CABLES), command))
            node.on_command(joint_state(NAMES, stamp, effort=command))
            node.on_twin(joint_state(NAMES, stamp, np.zeros(CABLES), np.zeros(CABLES),
                                     holding if tick >= failure_tick else command))
            node.on_reference(joint_state(NAMES, stamp, *reference))
        assert not node.diagnostics.rejected
        assert len(published[contract.FDI_RESIDUAL]) == failure_tick + extra_ticks
        assert [message.data for message in published[contract.FDI_BROKEN_CABLE]] == [cable + 1]
        modes = [message.data for message in published[contract.MODE]]
        assert modes and modes[0] in (contract.RECOVERY_TENSION, contract.RECOVERY_MOVE,
                                      contract.FAULT)
        assert_sane_verdicts(published)


# ---- trajectory generator -------------------------------------------------------------

WORKSPACE_MIN, WORKSPACE_MAX = ROBOT.workspace_min_m, ROBOT.workspace_max_m
GOAL_HOME = tuple(ROBOT.home_position_m)


def inside_workspace(point) -> bool:
    return all(map(math.isfinite, point)) and bool(
        np.all(np.array(point) >= WORKSPACE_MIN) and np.all(np.array(point) <= WORKSPACE_MAX))


# Goals the generator must plan: central, and far enough from home (every goal move here
# starts there) that the quintic's peak acceleration, about 0.41 / length m/s², stays
# well below g. Shorter moves (1 mm – 5 cm) and goals near the box's corners, e.g.
# (0, 0, 2.2), cannot be planned and are rejected (test_watchdogs).
plannable_goals = central_points.filter(
    lambda point: math.dist(point, GOAL_HOME) >= 0.2)
any_coordinates = st.one_of(st.floats(-1.0, 3.0), any_values)
unplannable_goals = st.tuples(any_coordinates, any_coordinates, any_coordinates).filter(
    lambda point: not inside_workspace(point))


@pytest.fixture(scope='module')
def trajectory_generator(clock_mode):
    """One generator for the module (building one tabulates the whole circle), at home,
    its time origin set by a state stamped 0."""
    with fresh(TrajectoryGeneratorNode) as (node, published):
        node.on_goal(point_stamped(0, GOAL_HOME))
        node.on_state(joint_state(NAMES, 0))
        yield node, published


def plan_ids(node):
    """The planned segments, by identity: a goal appends one and never edits any."""
    return [(start, id(table)) for start, table in node.schedule.segments]


@settings(FUZZ, max_examples=examples(25))
@pytest.mark.parametrize('clock_mode', ['lockstep'], indirect=True)
@given(goal=st.one_of(plannable_goals, unplannable_goals))
def test_trajectory_generator_plans_finite_goals_in_the_workspace_only(
        clock_mode, trajectory_generator, goal):
    node, published = trajectory_generator
    segments = len(node.schedule.segments)
    valid = inside_workspace(goal)
    deliver(node, published, 'on_goal', point_stamped(0, goal), contract.GOAL, valid, plan_ids)
    if valid:
        assert len(node.schedule.segments) == segments + 1
        table = node.schedule.segments[-1][1]
        for column in (table.position_m, table.angle_rad, table.angular_velocity_rad_s,
                       table.feedforward_nm):
            assert np.all(np.isfinite(column))
        np.testing.assert_allclose(table.position_m[-1], goal, atol=1e-9)
        node.on_goal(point_stamped(0, GOAL_HOME))
        assert len(node.schedule.segments) == segments + 2


# After a state stamped far ahead the generator goes on from that tick; jumps here stay
# within one second so that examples stay quick.
MAX_JUMP_TICKS = 500


@settings(FUZZ, max_examples=examples(50))
@pytest.mark.parametrize('clock_mode', ['lockstep'], indirect=True)
@given(jumps=st.lists(st.tuples(st.integers(-50, MAX_JUMP_TICKS), st.integers(0, PERIOD_NS - 1),
                                joint_states(st.just(0))), min_size=1, max_size=10))
def test_trajectory_generator_publishes_each_reference_once_in_order(
        clock_mode, trajectory_generator, jumps):
    """Only the stamp of a state counts (its content is never used): the references from
    the next unpublished tick (or, after a jump ahead, from the new tick: those jumped
    over are of no use) up to `reference_lead_cycles` ahead, each once, in order."""
    node, published = trajectory_generator
    references, poses = published[contract.REFERENCE], published[contract.REFERENCE_POSE]
    rejected = Counter(node.diagnostics.rejected)
    for jump, offset, message in jumps:
        count, posed, first = len(references), len(poses), node.schedule.next_tick
        latest_tick = first - LEAD_CYCLES - 1
        stamp = (latest_tick + jump) * PERIOD_NS + offset + (node.origin_ns or 0)
        message.header.stamp = ns_to_stamp(stamp)
        node.on_state(message)
        tick = (stamp - node.origin_ns) // PERIOD_NS
        expected = list(range(max(first, tick), tick + LEAD_CYCLES + 1))
        # the pose, a view topic, of the view ticks among them only
        viewed = [later for later in expected if node.view_ticks.at(node.origin_ns + later * PERIOD_NS)]
        for sent, ticks in ((references[count:], expected), (poses[posed:], viewed)):
            assert [(stamp_to_ns(m.header.stamp) - node.origin_ns) // PERIOD_NS for m in sent] == ticks
            assert all((stamp_to_ns(m.header.stamp) - node.origin_ns) % PERIOD_NS == 0 for m in sent)
        assert_finite_joint_states(references[count:])
    assert node.diagnostics.rejected == rejected


# ---- config loaders -------------------------------------------------------------------

# The paper robot's file as the loaders see it, every default filled in, is what is
# mutated; a key deleted from it then falls back on defaults/
SHIPPED = copy.deepcopy(dict(load_config(PAPER_ROBOT).data))
# What each key of it must be and which loaders must read it, written by hand.
KEY_TABLE = load_yaml(Path(__file__).with_name('config_keys.yaml'))
MISSING = object()   # the value of a deleted key


def controller_core(path, robot):
    """The control section as the controller builds its core from it."""
    control = load_section(path, 'control')
    return (PdGains.from_section(robot, control), FrictionModel.of_robot(robot, control),
            configured_tension_distribution(control, robot))


# name: load(path, robot) of each loader under test; `robot` serves the loaders that need
# one when the mutated file's own robot does not load. 'robot' first: the others get its robot.
LOADERS = {
    'robot': lambda path, robot: load_robot(path),
    'control': controller_core,
    'fdi': lambda path, robot: load_fdi_config(path, robot),
    'recovery': lambda path, robot: load_recovery_config(path, robot),
    'plant': lambda path, robot: PlantConfig.from_section(load_section(path, 'plant'), robot.cable_count),
    'markers': lambda path, robot: MarkerStyle.from_section(load_section(path, 'markers')),
    'scheduling': lambda path, robot: realtime_scheduling(load_section(path, 'scheduling')),
    # as CdprNode.configure reads them
    'health': lambda path, robot: HealthLimits.from_section(load_config(path).section('health', {})),
    'streams': lambda path, robot: (qos.stream_writer(load_config(path).section('streams', {}), 0.002),
                                    contract.ViewTicks.of_streams(load_config(path).section('streams', {}), 0.002)),
}


@contextmanager
def own_rclpy(config):
    """Inside the block, nodes are made in an rclpy context of their own, started on the
    robot file `config` as by hand; the module's other nodes keep theirs."""
    context = rclpy.Context()
    rclpy.init(args=['--ros-args', '-p', f'config_file:={config}', '-p', f'motions_file:={MOTIONS}'],
               context=context)
    try:
        with pytest.MonkeyPatch.context() as patch:
            patch.setattr(rclpy.node, 'get_default_context', lambda: context)
            yield
    finally:
        rclpy.shutdown(context=context)


def built(node_class):
    """A node as the loader of the keys it reads itself (inside own_rclpy on the file)."""
    return lambda path, robot: node_class().destroy_node()


NODE_LOADERS = {'controller_node': built(ControllerNode), 'digital_twin_node': built(DigitalTwinNode),
                'supervisor_node': built(SupervisorNode), 'plant_simulator_node': built(PlantSimulatorNode),
                'trajectory_generator_node': built(TrajectoryGeneratorNode)}
ALL_LOADERS = LOADERS | NODE_LOADERS


def paths(tree, prefix=()):
    """Every path (tuple of keys and list indices) below the root of `tree`."""
    items = tree.items() if isinstance(tree, dict) else enumerate(tree) if isinstance(tree, list) else ()
    for key, value in items:
        yield prefix + (key,)
        yield from paths(value, prefix + (key,))


def dotted_key(tree, path) -> str:
    """The config key a path lies under, dotted; list indices are part of that key's value."""
    keys, node = [], tree
    for step in path:
        if isinstance(node, dict):
            keys.append(str(step))
        node = node[step]
    return '.'.join(keys)


def without_indices(key: str) -> str:
    return re.sub(r'\[\d+\]', '', key)


KNOWN_KEYS = {dotted_key(SHIPPED, path) for path in paths(SHIPPED)}
# every key that holds a value, not a mapping of keys (an empty mapping is a value)
VALUE_KEYS = {dotted_key(SHIPPED, path) for path in paths(SHIPPED)
              if not (isinstance(value := reduce(getitem, path, SHIPPED), dict) and value)}
# keys a robot file may leave out
DEFAULT_KEYS = {dotted_key(paper_defaults(), path) for path in paths(paper_defaults())}


def names_key(named: str, key: str) -> bool:
    """An error on `named` is one on `key`: the key itself, an element of its list, or an
    entry of its mapping (recovery.safe_points_m.4)."""
    return without_indices(named) == key or named.startswith(f'{key}.')


def is_number(value) -> bool:
    """A number as YAML writes one, finite as a float; a bool is none."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    try:
        return math.isfinite(value)
    except OverflowError:
        return False


def within(spec, number) -> bool:
    return (number > spec.get('above', -math.inf) and number >= spec.get('at_least', -math.inf)
            and number < spec.get('below', math.inf) and number <= spec.get('at_most', math.inf))


def is_point(value) -> bool:
    return isinstance(value, list) and len(value) == 3 and all(map(is_number, value))


def is_safe_point(cable, point) -> bool:
    low, high = SHIPPED['robot']['workspace_m']['min'], SHIPPED['robot']['workspace_m']['max']
    return (isinstance(cable, int) and not isinstance(cable, bool) and 1 <= cable <= CABLES
            and is_point(point) and all(a <= x <= b for a, x, b in zip(low, point, high))
            and point[2] > SHIPPED['recovery']['table_height_m'])


def in_range(spec, value) -> bool:
    """`value` is of the kind and in the range the table gives (config_keys.yaml's head)."""
    kind = spec['is']
    if kind == 'number':
        return is_number(value) and within(spec, value)
    if kind == 'integer':
        return (isinstance(value, int) and not isinstance(value, bool) and -2 ** 63 <= value < 2 ** 63
                and within(spec, value))
    if kind in ('choice', 'text'):
        return isinstance(value, str) and (kind == 'text' or value in spec['one_of'])
    if kind in ('point', 'downward'):
        return is_point(value) and (kind == 'point' or value[2] < 0)
    if kind == 'points':
        return isinstance(value, list) and len(value) >= spec['cables_at_least'] and all(map(is_point, value))
    if kind == 'per_cable':
        values = value if isinstance(value, list) and len(value) == CABLES else [value]
        return all(is_number(number) and within(spec, number) for number in values)
    if kind == 'angles':
        return isinstance(value, list) and bool(value) and all(is_number(n) and within(spec, n) for n in value)
    if kind == 'safe_points':
        return isinstance(value, dict) and all(is_safe_point(*item) for item in value.items())
    raise AssertionError(f'config_keys.yaml: no kind {kind!r}')


def value_at(tree, key: str):
    for name in key.split('.'):
        if not isinstance(tree, dict) or name not in tree:
            return MISSING
        tree = tree[name]
    return tree


def verdict(tree, key: str) -> tuple[str | None, list[str]]:
    """What the table says the loaders that read `key` (returned) must do with the file
    `tree`: 'refused' (naming `key`), 'accepted', or None where the range depends on other
    keys (`with`). A mapping of keys holds the keys below it."""
    value = value_at(tree, key)
    if key in KEY_TABLE:
        spec = KEY_TABLE[key]
        if value is MISSING:
            return ('refused' if spec.get('required') else 'accepted'), spec['read_by']
        if not in_range(spec, value):
            return 'refused', spec['read_by']
        return (None if 'with' in spec else 'accepted'), spec['read_by']
    below = [KEY_TABLE[inner] for inner in KEY_TABLE if inner.startswith(f'{key}.')]
    loaders = sorted({name for spec in below for name in spec['read_by']})
    if value is MISSING:
        return ('refused' if any(spec.get('required') for spec in below) else 'accepted'), loaders
    return ('refused' if not isinstance(value, dict) else None), loaders


def mutated(path, value) -> dict:
    tree = copy.deepcopy(SHIPPED)
    parent = reduce(getitem, path[:-1], tree)
    if value is MISSING:
        del parent[path[-1]]
    else:
        parent[path[-1]] = value
    return tree


def refusals(config, names, parsed) -> dict[str, ConfigError]:
    """name → the ConfigError of each loader among `names` that refused the robot file
    `config` (as `parsed` holds it, else as written); each names that file and a key of
    the shipped file."""
    refused = {}
    with parsing_once(parsed):
        robot = ROBOT
        for name in sorted(names, key=lambda name: name != 'robot'):
            try:
                loaded = ALL_LOADERS[name](config, robot)
            except ConfigError as err:
                # a node adds where it took its parameters from
                assert err.path.startswith(str(config)), err
                assert str(err).startswith(f"{err.path}: '{err.key}' "), err
                assert without_indices(err.key) in KNOWN_KEYS or any(
                    names_key(err.key, key) for key in VALUE_KEYS), err
                refused[name] = err
            else:
                if name == 'robot':
                    robot = loaded
    return refused


def check_verdict(refused, loaders, key, expected, value) -> None:
    for name in loaders:
        if expected == 'refused':
            assert name in refused, f'{name} took {key} {"deleted" if value is MISSING else f"= {value!r}"}'
            assert names_key(refused[name].key, key), refused[name]
        elif expected == 'accepted':
            assert name not in refused, refused[name]


def test_the_key_table_covers_every_key_of_the_shipped_file():
    """A key added to the robot file or to defaults/ must be added to config_keys.yaml;
    the table's own values agree with its ranges."""
    assert set(KEY_TABLE) == VALUE_KEYS
    assert len(KEY_TABLE) >= 100
    for key, spec in KEY_TABLE.items():
        assert set(spec['read_by']) <= set(ALL_LOADERS), key
        assert spec['read_by'] or spec['unread'], key
        assert not (spec.get('required') and key in DEFAULT_KEYS), key
        assert in_range(spec, value_at(SHIPPED, key)), key
        if spec['read_by']:
            assert spec['valid'] and all(in_range(spec, value) for value in spec['valid']), key
    # the robot's name, geometry, mass, motors and tension bounds
    assert sum(bool(spec.get('required')) for spec in KEY_TABLE.values()) == 15


# a deleted key, and values of every wrong kind, out of range, or in it
WRONG = [MISSING, 'twelve', '12', '', None, math.nan, True, False, [], [1.0] * (CABLES + 1),
         -1, -1e-300, 0, 0.0, HUGE, 10 ** 400, -10 ** 400]


def key_cases():
    """(key, value, what the table says of it, the loaders bound by it) for every key a
    loader reads: deleted, of each wrong kind, out of range and in it, its invalid values,
    and its valid ones, which every loader must accept."""
    for key, spec in KEY_TABLE.items():
        if spec['read_by']:
            path = tuple(key.split('.'))
            for value in WRONG:
                yield key, value, verdict(mutated(path, value), key)[0], spec['read_by']
            yield from ((key, value, 'refused', spec['read_by']) for value in spec.get('invalid', []))
            yield from ((key, value, 'accepted', spec['read_by'] + list(LOADERS)) for value in spec['valid'])


def test_each_loader_refuses_the_deletion_of_each_key_it_requires(tmp_path):
    """A loader that stops reading a required key takes a file without it."""
    config = tmp_path / 'robot.yaml'
    checked = 0
    with own_rclpy(config):
        for key, spec in KEY_TABLE.items():
            if spec.get('required'):
                without = mutated(tuple(key.split('.')), MISSING)
                refused = refusals(config, spec['read_by'], {str(config): without})
                check_verdict(refused, spec['read_by'], key, 'refused', MISSING)
                checked += len(spec['read_by'])
    assert checked == 15


def test_each_key_out_of_its_range_is_refused_naming_the_file_and_key(tmp_path):
    """Every key of the table, every kind of value: the loaders that read it refuse what
    lies outside its range, naming it; what is inside they accept, and every other loader
    too for the valid values."""
    config = tmp_path / 'robot.yaml'
    verdicts = Counter()
    with own_rclpy(config):
        for key, value, expected, loaders in key_cases():
            refused = refusals(config, set(loaders), {str(config): mutated(tuple(key.split('.')), value)})
            check_verdict(refused, loaders, key, expected, value)
            verdicts[expected] += 1
    read = [spec for spec in KEY_TABLE.values() if spec['read_by']]
    assert sum(verdicts.values()) == sum(len(WRONG) + len(spec['valid']) + len(spec.get('invalid', []))
                                         for spec in read)
    assert verdicts['refused'] >= 1500 and verdicts['accepted'] >= 300, verdicts


def replacements(path, kind):
    original = reduce(getitem, path, SHIPPED)
    numbers = st.one_of(st.integers(-10, 10), st.floats(-10.0, 10.0))
    if kind == 'wrong_length':
        # one value per cable is right where a number may also be given per cable
        # (fdi.cusum.sigma_nm)
        right = (len(original), CABLES) if isinstance(original, list) else (CABLES,)
        return st.lists(numbers, max_size=CABLES + 1).filter(lambda value: len(value) not in right)
    return {
        'delete': st.just(MISSING),
        'text': st.text(st.characters(codec='utf-8'), max_size=20),
        'none': st.none(),
        'nan': st.just(math.nan),
        'bool': st.booleans(),
        'negative': st.one_of(st.integers(max_value=-1), st.floats(max_value=-1e-300, min_value=-HUGE)),
        'zero': st.sampled_from([0, 0.0]),
        # YAML writes integers of any size; they exceed the float range
        'huge': st.sampled_from([10 ** 400, -10 ** 400, HUGE]),
    }[kind]


KINDS = ('delete', 'text', 'none', 'nan', 'bool', 'negative', 'zero', 'huge', 'wrong_length')
mutations = st.tuples(st.sampled_from(list(paths(SHIPPED))), st.sampled_from(KINDS)).flatmap(
    lambda mutation: st.tuples(st.just(mutation[0]), st.just(mutation[1]), replacements(*mutation)))


@settings(FUZZ, max_examples=examples(150))
@given(mutation=mutations)
# What the loaders took for numbers before config.py checked vectors element by element
# (True as 1.0, '1.0' as 1.0) or raised on (OverflowError on an integer beyond float).
@example(mutation=(('robot', 'home_position_m', 2), 'bool', True))
@example(mutation=(('robot', 'home_position_m', 2), 'text', '1.0'))
@example(mutation=(('robot', 'end_effector', 'mass_kg'), 'huge', 10 ** 400))
@example(mutation=(('robot', 'gravity_m_s2', 2), 'huge', -10 ** 400))
def test_config_loaders_accept_or_name_the_file_and_key(tmp_path_factory, mutation):
    """Random mutations anywhere in the shipped file (an element of a list, a whole
    section), written as YAML: each loader loads it or names the file and a key, and the
    loaders that read the key do what the table says."""
    path, kind, value = mutation
    config = tmp_path_factory.mktemp('config') / 'robot.yaml'
    tree = mutated(path, value)
    config.write_text(yaml.safe_dump(tree))
    refused = refusals(config, LOADERS, {})
    key = dotted_key(SHIPPED, path)
    expected, loaders = verdict(tree, key)
    check_verdict(refused, [name for name in loaders if name in LOADERS], key, expected, value)
