"""The ros2_control bridge (issue 14, item 6): the core (cdpr_twin.nodes.joint_mapping)
directly, then the node in this process on DDS between stand-ins shaped like
joint_state_broadcaster (joints in another order, an extra joint) and a
JointGroupEffortController (Float64MultiArray in its own joint order)."""
from __future__ import annotations

import time

import numpy as np
import pytest

from cdpr_control.point_mass.kinematics import forward_kinematics
from cdpr_control.platform.kinematics import inverse_kinematics
from cdpr_control.setup.robot_file import load_robot
from cdpr_control.geometry.rotation import difference, from_axis_angle
from cdpr_control.point_mass.statics import holding_torque_nm
from cdpr_msgs_py.contract import joint_names
from cdpr_twin.nodes.joint_mapping import EffortBridge, JointMapping, JointMismatch, StaleWatch, TickStamps
from cdpr_twin.models.rigid_model import RigidModel

from conftest import CONFIG_DIR, PAPER_ROBOT

MOTORS = joint_names(4)
ROBOT_JOINTS = ['winch_a', 'winch_b', 'winch_c', 'winch_d']        # motor_1 … motor_4
CONTROLLER_JOINTS = ['winch_c', 'winch_a', 'winch_d', 'winch_b']   # the controller's order
# as joint_state_broadcaster lists them: its own order, with a joint that is not ours
BROADCAST = ['gripper', 'winch_d', 'winch_b', 'winch_a', 'winch_c']


def mapping() -> JointMapping:
    return JointMapping(MOTORS, ROBOT_JOINTS, CONTROLLER_JOINTS)


# ---- the core -------------------------------------------------------------------------

def test_joints_are_matched_by_name_in_any_order_and_extra_joints_ignored():
    values = {'gripper': 9.0, 'winch_d': 4.0, 'winch_b': 2.0, 'winch_a': 1.0, 'winch_c': 3.0}
    ordered = mapping().motor_order(BROADCAST, {
        'position': [values[n] for n in BROADCAST], 'effort': [-values[n] for n in BROADCAST]})
    np.testing.assert_array_equal(ordered['position'], [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(ordered['effort'], [-1.0, -2.0, -3.0, -4.0])


def test_a_command_for_motor_k_lands_at_the_controllers_index_of_its_joint():
    assert mapping().controller_order([-0.1, -0.2, -0.3, -0.4]) == [-0.3, -0.1, -0.4, -0.2]


@pytest.mark.parametrize('names, fields, reason', [
    (['winch_d', 'winch_b', 'winch_a'], {'position': [0.0] * 3}, "joints ['winch_c'] missing"),
    (BROADCAST, {'effort': []}, 'effort has 0 values for 5 joints'),
    (BROADCAST, {'velocity': [0.0, 0.0, float('nan'), 0.0, 0.0]}, 'non-finite'),
    (['winch_a', *BROADCAST], {'position': [0.0] * 6}, 'named twice'),
])
def test_a_sample_missing_one_of_our_joints_or_values_is_rejected_with_its_reason(names, fields, reason):
    with pytest.raises(JointMismatch, match=reason.replace('[', r'\[').replace(']', r'\]')):
        mapping().motor_order(names, fields)


def test_a_nan_in_a_joint_that_is_not_ours_is_ignored():
    fields = {'position': [float('nan'), 4.0, 2.0, 1.0, 3.0]}
    np.testing.assert_array_equal(mapping().motor_order(BROADCAST, fields)['position'], [1, 2, 3, 4])


@pytest.mark.parametrize('robot_joints, controller_joints', [
    (['winch_a', 'winch_b', 'winch_c'], ['winch_a', 'winch_b', 'winch_c']),
    (ROBOT_JOINTS, ['winch_a', 'winch_b', 'winch_c']),
    (ROBOT_JOINTS, ['winch_a', 'winch_b', 'winch_c', 'winch_e']),
    (['winch_a', 'winch_a', 'winch_c', 'winch_d'], ROBOT_JOINTS),
])
def test_joint_lists_that_cannot_drive_every_motor_are_refused(robot_joints, controller_joints):
    with pytest.raises(ValueError, match='parameter'):
        JointMapping(MOTORS, robot_joints, controller_joints)


def test_samples_land_on_the_tick_grid_and_one_not_after_the_last_tick_is_rejected():
    period = 2_000_000
    ticks = TickStamps(period)
    start = 1_700_000_000_123_456_789   # the robot's wall clock
    assert ticks.stamp_ns(start) == 0
    assert ticks.stamp_ns(start + period + 300_000) == period   # jitter rounds to its tick
    assert ticks.stamp_ns(start + 3 * period) == 3 * period     # a lost sample leaves a gap
    with pytest.raises(JointMismatch, match='not after tick 3'):
        ticks.stamp_ns(start + 3 * period + 100_000)


def test_robot_data_silent_for_stale_cycles_periods_is_stale():
    watch = StaleWatch(stale_cycles=50, period_s=0.002, started_s=10.0)
    assert not watch.stale(10.1)
    assert watch.stale(10.1001)
    watch.arrived(10.2)
    assert not watch.stale(10.25) and watch.silent_s(10.25) == pytest.approx(0.05)


@pytest.fixture(scope='module')
def robot():
    from cdpr_control.setup.robot_file import load_robot
    return load_robot(PAPER_ROBOT)


def test_silent_controller_the_bridge_holds_the_load_with_static_torques_never_zero(robot):
    bridge = EffortBridge(robot, hold_cycles=3)
    angles = np.array([0.01, -0.02, 0.015, 0.0])
    attached = robot.cable_mask()
    holding = holding_torque_nm(robot, forward_kinematics(robot, angles, attached), attached)
    assert bridge.tick(None) is None, 'no pose measured yet: nothing to compute from'
    np.testing.assert_allclose(bridge.tick(angles), holding)   # before the first command
    assert bridge.holding and np.all(holding < 0)
    sent = bridge.command_nm([-0.5, -0.6, -99.0, 99.0])
    np.testing.assert_array_equal(sent, [-0.5, -0.6, -robot.motor.torque_limit_nm,
                                         robot.motor.torque_limit_nm])
    # the effort controller applies the last command itself for hold_cycles periods
    assert [bridge.tick(angles) for _ in range(3)] == [None, None, None]
    np.testing.assert_allclose(bridge.tick(angles), holding)
    assert bridge.holding
    bridge.command_nm([-0.5] * 4)
    assert bridge.tick(angles) is None and not bridge.holding


def test_the_holding_torque_leaves_a_broken_cable_out(robot):
    bridge = EffortBridge(robot, hold_cycles=1)
    bridge.cable_broken(3)
    angles = np.zeros(4)
    attached = robot.cable_mask([3])
    held = bridge.tick(angles)
    np.testing.assert_allclose(held, holding_torque_nm(
        robot, forward_kinematics(robot, angles, attached), attached).clip(
            -robot.motor.torque_limit_nm, robot.motor.torque_limit_nm))
    assert held[3] == 0.0
    with pytest.raises(ValueError):
        bridge.cable_broken(4)


def test_a_platforms_holding_torques_hold_it_at_its_measured_pose():
    """Eight joints of a platform, its orientation tilted 10°: the bridge finds the pose
    from the angles and sends the torques that keep it there, with every cable pulling;
    the rigid platform under them does not move. One cable broken: the seven others hold
    it, and with only five left no pose can be found, the last torques stay."""
    platform = load_robot(CONFIG_DIR / 'robots' / 'crossed_platform_robot.yaml')
    position = platform.home_position_m + np.array([0.1, -0.05, 0.1])
    orientation = from_axis_angle([1.0, 1.0, 0.0], np.radians(10.0))
    angles = inverse_kinematics(platform, position, orientation)
    for broken in ([], [6]):
        bridge = EffortBridge(platform, hold_cycles=1)
        for cable in broken:
            bridge.cable_broken(cable)
        held = bridge.tick(angles)
        assert bridge.holding and held.shape == (8,)
        assert np.all(held[platform.cable_mask(broken)] < 0.0) and np.all(held[broken] == 0.0)
        model = RigidModel(platform, position, orientation)
        model.break_cables(broken)
        for _ in range(50):
            model.step(held, 0.002)
        assert np.linalg.norm(model.position_m - position) < 1e-9
        assert np.linalg.norm(difference(model.orientation, orientation)) < 1e-9
    bridge.command_nm(held)
    for cable in (0, 1):
        bridge.cable_broken(cable)
    bridge.tick(angles)
    np.testing.assert_array_equal(bridge.tick(angles), held)


def test_with_fewer_than_three_cables_the_last_torques_sent_stay(robot):
    bridge = EffortBridge(robot, hold_cycles=1)
    bridge.command_nm([-0.4, -0.3, 0.0, 0.0])
    bridge.cable_broken(2)
    bridge.cable_broken(3)
    bridge.tick(np.zeros(4))
    np.testing.assert_array_equal(bridge.tick(np.zeros(4)), [-0.4, -0.3, 0.0, 0.0])


# ---- the node, on DDS, between stand-ins ---------------------------------------------

WAIT_S = 10.0


@pytest.fixture(scope='module')
def graph():
    """rclpy with the bridge in /cdpr mapping winch_* to the motors, the stand-ins, and
    an executor spinning them all."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.node import Node
    from sensor_msgs.msg import JointState
    from std_msgs.msg import Float64MultiArray

    from cdpr_msgs_py import qos
    from cdpr_twin.nodes.ros2_control_bridge_node import ROS2_CONTROL_QOS, Ros2ControlBridgeNode

    def listed(names):
        return '[' + ','.join(names) + ']'

    rclpy.init(args=['--ros-args', '-r', 'ros2_control_bridge:__ns:=/cdpr',
                     '-p', f'config_file:={PAPER_ROBOT}',
                     '-p', f'robot_joints:={listed(ROBOT_JOINTS)}',
                     '-p', f'controller_joints:={listed(CONTROLLER_JOINTS)}'])
    bridge = Ros2ControlBridgeNode()
    broadcaster = Node('joint_state_broadcaster')
    effort_controller = Node('effort_controller')
    controller = Node('controller', namespace='/cdpr')   # the graph's, whose commands count
    received = {'commands': [], 'states': []}
    stand_ins = {
        'robot_states': broadcaster.create_publisher(JointState, '/joint_states', ROS2_CONTROL_QOS),
        'effort_command': controller.create_publisher(JointState, '/cdpr/effort_command', qos.STREAM),
    }
    effort_controller.create_subscription(Float64MultiArray, '/effort_controller/commands',
                                          lambda m: received['commands'].append(list(m.data)),
                                          ROS2_CONTROL_QOS)
    controller.create_subscription(JointState, '/cdpr/joint_states',
                                   lambda m: received['states'].append(m), qos.STREAM)
    executor = SingleThreadedExecutor()
    for node in (bridge, broadcaster, effort_controller, controller):
        executor.add_node(node)

    def spin_until(condition, what: str, limit_s: float = WAIT_S):
        deadline = time.monotonic() + limit_s
        while not condition():
            assert time.monotonic() < deadline, f'waited {limit_s} s for {what}'
            executor.spin_once(timeout_sec=0.01)
            bridge.idle()

    yield bridge, stand_ins, received, spin_until
    executor.shutdown()
    for node in (bridge, broadcaster, effort_controller, controller):
        node.destroy_node()
    rclpy.shutdown()


def broadcast(publisher, stamp_ns, values: dict[str, float], names=BROADCAST):
    from cdpr_msgs_py.conversions import joint_state
    publisher.publish(joint_state(names, stamp_ns, [values.get(n, 0.0) for n in names],
                                  [10 * values.get(n, 0.0) for n in names],
                                  [-values.get(n, 0.0) for n in names]))


def test_node_turns_the_robot_into_the_contract_and_back(graph, robot):
    from diagnostic_msgs.msg import DiagnosticStatus
    bridge, stand_ins, received, spin_until = graph
    spin_until(lambda: stand_ins['robot_states'].get_subscription_count() > 0
               and bridge.commands.get_subscription_count() > 0
               and stand_ins['effort_command'].get_subscription_count() > 0
               and bridge.state.get_subscription_count() > 0 and bridge.matched(),
               'the endpoints to match and the controller to be pinned')
    # a state of joint X lands on its motor, stamped on the tick grid
    angles = {'winch_a': 0.01, 'winch_b': -0.02, 'winch_c': 0.015, 'winch_d': 0.0, 'gripper': 7.0}
    start_ns = time.time_ns()
    broadcast(stand_ins['robot_states'], start_ns, angles)
    spin_until(lambda: received['states'], 'our joint_states')
    state = received['states'][-1]
    assert list(state.name) == MOTORS
    assert list(state.position) == [angles[j] for j in ROBOT_JOINTS]
    assert list(state.velocity) == [10 * angles[j] for j in ROBOT_JOINTS]
    assert list(state.effort) == [-angles[j] for j in ROBOT_JOINTS]
    assert state.header.stamp.sec == 0 and state.header.stamp.nanosec == 0
    # no command yet: the load is held with the static torques of the measured pose
    motor_angles = np.array([angles[j] for j in ROBOT_JOINTS])
    attached = robot.cable_mask()
    holding = holding_torque_nm(robot, forward_kinematics(robot, motor_angles, attached), attached)
    expected_holding = [holding[ROBOT_JOINTS.index(j)] for j in CONTROLLER_JOINTS]
    spin_until(lambda: received['commands'], 'the holding torques')
    np.testing.assert_allclose(received['commands'][-1], expected_holding)
    # a command for motor_k lands at the controller's index of its joint
    from cdpr_msgs_py.conversions import joint_state
    command = [-0.1, -0.2, -0.3, -0.4]
    received['commands'].clear()
    stand_ins['effort_command'].publish(joint_state(MOTORS, 0, effort=command))
    spin_until(lambda: [-0.3, -0.1, -0.4, -0.2] in received['commands'], 'the command, reordered')
    assert bridge.diagnostics.totals['commands'] == 1
    # the commands stop: after plant.command_timeout_cycles periods the static torques again
    spin_until(lambda: received['commands'][-1] != [-0.3, -0.1, -0.4, -0.2], 'the watchdog')
    np.testing.assert_allclose(received['commands'][-1], expected_holding)
    assert bridge.holding
    errors, _ = bridge.current_problems()
    assert any('no command for' in e and 'holding the load' in e for e in errors), errors
    # a message missing one of our joints is rejected and counted, the last state kept
    count = len(received['states'])
    broadcast(stand_ins['robot_states'], start_ns + 2_000_000, angles,
              names=['gripper', 'winch_d', 'winch_a', 'winch_c'])
    spin_until(lambda: bridge.diagnostics.rejected['/joint_states'] == 1, 'the rejection')
    assert len(received['states']) == count
    # no robot data for control.stale_cycles periods: ERROR naming the topic
    spin_until(lambda: bridge.robot_stale, 'stale robot data')
    sent = []
    bridge.diagnostics.publisher.publish = sent.append
    bridge.diagnostics.publish()
    status = sent[-1].status[0]
    assert status.level == DiagnosticStatus.ERROR
    assert 'no joint states from the robot on /joint_states' in status.message
    # the joint lists cannot change under a running bridge
    assert all(bridge.describe_parameter(name).read_only and bridge.describe_parameter(name).description
               for name in ('robot_joints', 'controller_joints', 'robot_joint_states_topic',
                            'controller_commands_topic', 'command_writer'))


def test_the_example_configuration_drives_every_motor_through_its_effort_controller():
    import yaml
    from conftest import CONFIG_DIR
    example = yaml.safe_load((CONFIG_DIR / 'ros2_control_example.yaml').read_text())
    bridge = example['/cdpr/ros2_control_bridge']['ros__parameters']
    controller_joints = example['effort_controller']['ros__parameters']['joints']
    assert bridge['controller_joints'] == controller_joints
    assert example['controller_manager']['ros__parameters']['effort_controller']['type'] == \
        'effort_controllers/JointGroupEffortController'
    JointMapping(MOTORS, bridge['robot_joints'], bridge['controller_joints'])
