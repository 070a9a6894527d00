"""Watchdogs without DDS: the drive's command watchdog and brake, the FDI's late-command guard."""
from __future__ import annotations

import time

import numpy as np
import pytest
from diagnostic_msgs.msg import DiagnosticStatus

from cdpr_bringup.runs.settle import ScenarioOptions, build_scenario
from cdpr_control.control.controller import JointReference
from cdpr_fdi.supervision.supervisor import Supervisor
from cdpr_twin.models.plant import FIDELITIES, PlantSimulator
from cdpr_twin.nodes.watchdog import BRAKING, HOLDING, OK, CommandWatchdog

from conftest import MOTIONS, PAPER_ROBOT, kept


def test_watchdog_holds_then_brakes_and_a_fresh_command_releases():
    watchdog = CommandWatchdog(hold_cycles=3)
    watchdog.command_arrived()
    assert [watchdog.tick() for _ in range(5)] == [OK, HOLDING, HOLDING, BRAKING, BRAKING]
    watchdog.command_arrived()
    assert watchdog.tick() == OK
    with pytest.raises(ValueError):
        CommandWatchdog(0)


@pytest.mark.parametrize('fidelity', FIDELITIES)
def test_braked_drums_hold_the_load_where_zero_torque_drops_it(fidelity):
    scenario = build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                              motion='circle', fidelity=fidelity))
    robot, start = scenario.robot, scenario.reference.position_m[0]
    braked = PlantSimulator(robot, scenario.plant, start)
    dropped = PlantSimulator(robot, scenario.plant, start)
    braked.lock_drums(True)
    angles = braked.model.angle_rad.copy()
    for _ in range(250):   # half a second without any command
        braked.step(np.zeros(robot.cable_count), scenario.period_s)
        dropped.step(np.zeros(robot.cable_count), scenario.period_s)
    np.testing.assert_array_equal(braked.model.angle_rad, angles)
    assert start[2] - braked.position_m[2] < 0.005
    assert start[2] - dropped.position_m[2] > 0.1
    # released, the drive holds the load again with its holding torques
    braked.lock_drums(False)
    braked.step(braked.holding_torque_nm(), scenario.period_s)
    assert not braked.drums_locked


def late_command_supervisor():
    scenario = build_scenario(ScenarioOptions(config=str(PAPER_ROBOT), motions=str(MOTIONS),
                                              motion='along-2', fidelity='rigid'))
    supervisor = Supervisor(scenario.robot, scenario.fdi, scenario.recovery, scenario.distribution,
                            scenario.period_s)
    return supervisor, scenario.fdi, scenario.robot.cable_count


def test_a_burst_of_late_commands_suspends_judgement_instead_of_raising_an_alarm():
    supervisor, fdi, m = late_command_supervisor()
    reference = JointReference(np.zeros(m), np.zeros(m), np.zeros(m))
    command = np.full(m, -0.4)
    off_by_timing = command + np.array([0.5, 0.0, 0.0, 0.0])   # far above ε = 0.03 N·m
    zero = np.zeros(m)
    supervisor.update(0, zero, zero, command, command, command, zero, reference)
    # a burst: every tick the drive applied something older than the last command
    burst = fdi.late_command_burst
    verdicts = [supervisor.update(k, zero, zero, command + 0.1 * k, off_by_timing, command, zero,
                                  reference) for k in range(1, burst + 1)]
    assert supervisor.late_commands == burst
    # the residual of the following ticks is timing
    last = burst + fdi.late_command_guard_cycles
    verdicts += [supervisor.update(k, zero, zero, off_by_timing, off_by_timing, command, zero, reference)
                 for k in range(burst + 1, last + 1)]
    assert not any(v.alarm for v in verdicts[burst - 1:])
    assert supervisor.summary()['unjudged_ticks'] == last - burst + 1
    # once the guard has run out, the same residual is evidence again
    assert supervisor.update(last + 1, zero, zero, off_by_timing, off_by_timing, command, zero,
                             reference).alarm


def test_an_isolated_late_command_does_not_blind_detection():
    supervisor, fdi, m = late_command_supervisor()
    reference = JointReference(np.zeros(m), np.zeros(m), np.zeros(m))
    command = np.full(m, -0.4)
    zero = np.zeros(m)
    supervisor.update(0, zero, zero, command, command, command, zero, reference)
    spacing = fdi.late_command_window_cycles   # never `burst` of them within the window
    alarms = []
    for k in range(1, 3 * spacing + 2):
        applied = command + 0.1 if k % spacing == 0 else command
        failed = command + np.array([0.5, 0.0, 0.0, 0.0]) if k == 3 * spacing + 1 else command
        alarms.append(supervisor.update(k, zero, zero, applied, failed, command, zero, reference).alarm)
    assert supervisor.late_commands == 3 and supervisor.summary()['unjudged_ticks'] == 0
    # the tick right after an isolated late command is judged: its residual raises the alarm
    assert alarms.index(True) == 3 * spacing


@pytest.fixture(scope='module')
def realtime_ros():
    """rclpy in this process, nodes in realtime clock mode; no peers: callbacks are called."""
    import rclpy
    rclpy.init(args=['--ros-args', '-p', f'config_file:={PAPER_ROBOT}', '-p', f'motions_file:={MOTIONS}',
                     '-p', 'clock_mode:=realtime'])
    yield
    rclpy.shutdown()


def joint_state_message(robot, stamp_ns, values):
    from cdpr_msgs_py.contract import joint_names
    from cdpr_msgs_py.conversions import joint_state
    m = robot.cable_count
    return joint_state(joint_names(m), stamp_ns, np.full(m, values), np.zeros(m), np.full(m, -0.4))


def diagnostics_status(node):
    """The /diagnostics status the node publishes now."""
    sent = []
    node.diagnostics.publisher.publish = sent.append
    node.diagnostics.publish()
    return sent[-1].status[0]


@pytest.fixture
def controller_node(realtime_ros):
    from cdpr_control.control.controller_node import ControllerNode
    node = ControllerNode()
    yield node
    node.destroy_node()


def test_controller_holds_when_joint_states_stop(controller_node, paper_robot):
    node = controller_node
    node.on_reference(joint_state_message(paper_robot, 0, 0.0))
    node.on_state(joint_state_message(paper_robot, 0, 0.0))
    assert node.controller.mode == 'NOMINAL'
    assert diagnostics_status(node).level == DiagnosticStatus.OK
    time.sleep(node.stale_ns / 1e9 * 1.5)
    node.idle()
    assert node.controller.mode == 'SAFE_HOLD'
    status = diagnostics_status(node)
    assert status.level == DiagnosticStatus.ERROR and 'no joint states' in status.message


def test_controller_holds_when_the_reference_goes_stale(controller_node, paper_robot):
    node = controller_node
    node.on_reference(joint_state_message(paper_robot, 0, 0.0))
    node.on_state(joint_state_message(paper_robot, node.stale_ns + node.period_ns, 0.0))
    assert node.controller.mode == 'SAFE_HOLD'
    status = diagnostics_status(node)
    assert status.level == DiagnosticStatus.ERROR and 'reference stale' in status.message


def test_supervisor_whose_twin_stops_reports_fdi_unavailable_as_error_and_raises_no_alarm(
        realtime_ros, paper_robot):
    from cdpr_fdi.nodes.supervisor_node import SupervisorNode
    node = SupervisorNode()
    try:
        period = node.period_ns
        twin_ticks = 10
        for k in range(3 * node.stale_ns // period):
            if k == twin_ticks:
                node.idle()
                assert diagnostics_status(node).level == DiagnosticStatus.OK, 'the FDI is on'
            node.on_state(joint_state_message(paper_robot, k * period, 0.0))
            node.on_command(joint_state_message(paper_robot, k * period, 0.0))
            node.on_reference(joint_state_message(paper_robot, k * period, 0.0))
            if k < twin_ticks:
                node.on_twin(joint_state_message(paper_robot, k * period, 0.0))
        node.idle()
        status = diagnostics_status(node)
        assert status.level == DiagnosticStatus.ERROR
        assert status.message.startswith('FDI unavailable: no twin')
        assert node.supervisor.alarm_tick is None and node.published_broken == []
    finally:
        node.destroy_node()


def test_controller_withholds_a_command_that_would_not_be_finite(controller_node, paper_robot):
    from cdpr_msgs_py.contract import joint_names
    from cdpr_msgs_py.conversions import joint_state
    node, m = controller_node, paper_robot.cable_count
    sent = []
    node.publisher.publish = kept(sent, node.publisher)
    node.on_reference(joint_state(joint_names(m), 0, [1e308] * m, [-1e308] * m, [0.0] * m))
    node.on_state(joint_state(joint_names(m), 0, [0.0] * m, [1e308] * m))
    assert sent == [] and node.diagnostics.rejected['joint_states'] == 1


def test_a_publish_that_fails_is_counted_and_reported_not_raised(controller_node, paper_robot,
                                                                 monkeypatch):
    """As every publish did once a stopped reader had filled a keep-all writer's history;
    raised in a callback, it ended the node and the graph."""
    from rclpy.impl.implementation_singleton import rclpy_implementation
    from rclpy.publisher import Publisher

    def cannot_publish(_publisher, _message):
        raise rclpy_implementation.RCLError('Failed to publish: cannot publish data')

    node = controller_node
    monkeypatch.setattr(Publisher, 'publish', cannot_publish)
    node.on_reference(joint_state_message(paper_robot, 0, 0.0))
    node.on_state(joint_state_message(paper_robot, 0, 0.0))
    topic = node.publisher.topic_name
    assert node.diagnostics.publish_failures == {topic: 1}
    status = diagnostics_status(node)
    assert status.level == DiagnosticStatus.WARN and status.message == f'publishing on {topic} failed'


@pytest.fixture
def realtime_generator(realtime_ros):
    """A realtime trajectory generator that has had the state of tick 0, and the
    references it published."""
    from cdpr_control.control.trajectory_generator_node import TrajectoryGeneratorNode
    node = TrajectoryGeneratorNode()
    sent = []
    node.reference.publish = kept(sent, node.reference)
    node.pose.publish = lambda message: None
    node.on_state(joint_state_message(node.robot, 0, 0.0))
    yield node, sent
    node.destroy_node()


def test_generator_rejects_a_goal_it_cannot_plan_and_survives_a_jump_in_time(realtime_generator):
    from geometry_msgs.msg import PointStamped
    node, sent = realtime_generator
    goal = PointStamped()
    goal.point.x, goal.point.y, goal.point.z = 0.0, 0.0, 2.2   # a corner: no tensions
    node.on_goal(goal)
    # realtime plans a few rows per tick; the ticks go on meanwhile
    ticks = 0
    while node.schedule.planning is not None and ticks < 1000:
        ticks += 1
        node.on_state(joint_state_message(node.robot, ticks * node.period_ns, 0.0))
    assert node.diagnostics.rejected['goal'] == 1 and len(node.schedule.segments) == 1
    status = diagnostics_status(node)
    assert status.level == DiagnosticStatus.WARN and status.message == 'rejected messages on goal'
    # 2**31 s later: only the references from there on, not 1e12 of them
    node.on_state(joint_state_message(node.robot, 2 ** 31 * 1_000_000_000, 0.0))
    assert len(sent) == 2 * (node.lead + 1) + ticks


def test_realtime_generator_keeps_publishing_while_it_plans_a_goal(realtime_generator):
    """What is planned, and where it is spliced, is test_reference_schedule's."""
    from cdpr_msgs_py.conversions import point_stamped, stamp_to_ns
    node, sent = realtime_generator
    period_ns = node.period_ns
    node.on_goal(point_stamped(0, np.array([1.1, 0.8, 1.35])))
    rows = node.schedule.planning[1].count
    # while the move is planned every tick still gets its reference, in order
    tick = 0
    while node.schedule.planning is not None:
        tick += 1
        node.on_state(joint_state_message(node.robot, tick * period_ns, 0.0))
        assert len(sent) == tick + node.lead + 1
    # on_goal planned the first rows, each tick the next ones
    assert tick == -(-rows // node.rows_per_tick) - 1
    stamps = [stamp_to_ns(message.header.stamp) for message in sent]
    assert stamps == [index * period_ns for index in range(len(sent))]
    # adopted after the circle and after what was already published
    (_, circle), (begin, _) = node.schedule.segments
    assert begin == max(len(circle), tick + node.lead)


def test_twin_bridges_a_gap_in_the_references_as_the_controller_does(realtime_ros, paper_robot):
    """Ticks that got no reference were answered by the controller with the last one it
    had; the twin steps them with that one too, and stays on the robot's clock."""
    from cdpr_control.control.controller import JointReference, PdGains
    from cdpr_control.config import load_section
    from cdpr_control.point_mass.kinematics import forward_kinematics
    from cdpr_control.geometry.motions import load_motion
    from cdpr_control.model.reference_table import tabulate_reference
    from cdpr_control.tension_distribution import configured_tension_distribution
    from cdpr_msgs_py.contract import joint_names
    from cdpr_msgs_py.conversions import joint_state
    from cdpr_twin.nodes.digital_twin_node import DigitalTwinNode
    from cdpr_twin.models.twin import DigitalTwin
    control = load_section(PAPER_ROBOT, 'control')
    motion = load_motion(MOTIONS, 'along-2', False)
    table = tabulate_reference(paper_robot, configured_tension_distribution(control, paper_robot),
                               motion.pose_trajectory, control.number('period_s'), duration_s=0.2)
    rows = [JointReference(table.angle_rad[k], table.angular_velocity_rad_s[k], table.feedforward_nm[k])
            for k in range(len(table))]
    node = DigitalTwinNode()
    try:
        published = []
        node.joints.publish = kept(published, node.joints)
        node.pose.publish = lambda message: None
        names = joint_names(paper_robot.cable_count)
        received = [0, 1, 2, 40, 41]   # the references of ticks 3 … 39 never came
        for k in received:
            row = rows[k]
            node.on_reference(joint_state(names, k * node.period_ns, row.angle_rad,
                                          row.angular_velocity_rad_s, row.feedforward_nm))
        assert node.diagnostics.totals['reference gaps'] == 1
        twin = DigitalTwin(paper_robot, PdGains.from_section(paper_robot, control),
                           forward_kinematics(paper_robot, rows[0].angle_rad), node.substeps)
        expected = [twin.step(rows[k if k in received else 2], node.period_s) for k in range(42)]
        # a state per reference received, none for the ticks bridged
        assert len(published) == len(received)
        for message, k in zip(published, received):
            np.testing.assert_allclose(message.position, expected[k].angle_rad, atol=1e-12)
            np.testing.assert_allclose(message.effort, expected[k].torque_nm, atol=1e-12)
    finally:
        node.destroy_node()
