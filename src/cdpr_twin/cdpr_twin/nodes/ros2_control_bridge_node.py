"""ros2_control_bridge: a ros2_control robot in the plant simulator's place (docs/hardware.md,
"ros2_control robots").

Reads joint_state_broadcaster's JointState (parameter `robot_joint_states_topic`,
joints matched by name through `robot_joints`) and publishes it as the graph's
`joint_states` in motor order, stamped on the tick grid; sends the graph's
`effort_command`, from the graph's controller only (`command_writer`), to a
JointGroupEffortController (`controller_commands_topic`, Float64MultiArray in the order
of `controller_joints`). The decisions are cdpr_twin.nodes.joint_mapping's: when the commands
stop it lets the effort controller hold the last one `plant.command_timeout_cycles`
periods, then sends the static holding torque of the measured pose; robot data silent
for `control.stale_cycles` periods is an ERROR in /diagnostics.
"""
from __future__ import annotations

import time

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64MultiArray, Int32

from cdpr_control.setup.settings import node_settings
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import joint_state_bytes
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run
from cdpr_msgs_py.stamps import seconds_to_ns, stamp_to_ns

from cdpr_twin.nodes.joint_mapping import EffortBridge, JointMapping, JointMismatch, StaleWatch, TickStamps

# What ros2_control's joint_state_broadcaster publishes and its forward command
# controllers subscribe with (rclcpp's SystemDefaultsQoS): reliable, volatile, keep last 10.
ROS2_CONTROL_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10,
                              reliability=ReliabilityPolicy.RELIABLE,
                              durability=DurabilityPolicy.VOLATILE)


class Ros2ControlBridgeNode(CdprNode):

    def __init__(self):
        super().__init__(contract.ROS2_CONTROL_BRIDGE)
        settings = node_settings(self, contract.ROS2_CONTROL_BRIDGE)
        self.robot, self.period_s = settings.robot, settings.period_s
        control = settings.section('control')
        self.names = contract.joint_names(self.robot.cable_count)
        robot_joints = self.parameter(
            'robot_joints', self.names,
            "the robot's joint names of motor_1 … motor_m, in that order")
        self.mapping = JointMapping(self.names, robot_joints, self.parameter(
            'controller_joints', robot_joints,
            "the JointGroupEffortController's `joints`, in its order: the order of its commands' data"))
        self.robot_states_topic = self.parameter(
            'robot_joint_states_topic', '/joint_states',
            "joint_state_broadcaster's sensor_msgs/JointState topic (absolute: outside the namespace)")
        commands_topic = self.parameter(
            'controller_commands_topic', '/effort_controller/commands',
            "the JointGroupEffortController's std_msgs/Float64MultiArray command topic")
        self.ticks = TickStamps(seconds_to_ns(self.period_s))
        self.robot_data = StaleWatch(control.integer('stale_cycles', minimum=1), self.period_s,
                                     time.monotonic())
        self.robot_stale = False
        self.bridge = EffortBridge(self.robot, settings.section('plant').integer(
            'command_timeout_cycles', minimum=1))
        self.holding = False
        self.angle_rad = None
        self.state = self.create_stream_publisher(JointState, contract.JOINT_STATES)
        self.commands = self.create_publisher(Float64MultiArray, commands_topic, ROS2_CONTROL_QOS)
        self.create_subscription(JointState, self.robot_states_topic, self.on_robot_state,
                                 ROS2_CONTROL_QOS)
        self.create_sole_writer_subscription(
            JointState, contract.EFFORT_COMMAND, self.on_command, qos.STREAM,
            self.parameter('command_writer', contract.CONTROLLER,
                                     'the node whose effort_command is obeyed (relative to the namespace)'))
        self.create_subscription(Int32, contract.FDI_BROKEN_CABLE, self.on_broken_cable, qos.LATCHED)
        self.create_timer(self.period_s, self.on_period)
        settings.declare(self)

    def on_robot_state(self, message: JointState) -> None:
        try:
            joints = self.mapping.motor_order(message.name, {
                'position': message.position, 'velocity': message.velocity, 'effort': message.effort})
            stamp_ns = self.ticks.stamp_ns(stamp_to_ns(message.header.stamp))
        except JointMismatch as err:
            self.diagnostics.reject(self.robot_states_topic, str(err))
            return
        self.robot_data.arrived(time.monotonic())
        self.angle_rad = joints['position']
        self.state.publish(joint_state_bytes(self.names, stamp_ns, joints['position'],
                                       joints['velocity'], joints['effort']))
        self.diagnostics.count('states')

    def on_command(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.EFFORT_COMMAND, ('effort',))
        if joints is None:
            return
        self.send(self.bridge.command_nm(joints.effort))
        self.diagnostics.count('commands')

    def on_broken_cable(self, message: Int32) -> None:
        if message.data == 0:
            return
        try:
            self.bridge.cable_broken(message.data - 1)
        except ValueError as err:
            self.diagnostics.reject(contract.FDI_BROKEN_CABLE, str(err))

    def send(self, torque_nm) -> None:
        self.commands.publish(Float64MultiArray(data=self.mapping.controller_order(torque_nm)))

    def on_period(self) -> None:
        torque = self.bridge.tick(self.angle_rad)
        if torque is not None:
            self.send(torque)
            self.diagnostics.count('holding ticks')
        now_s = time.monotonic()
        if self.bridge.holding != self.holding or self.robot_data.stale(now_s) != self.robot_stale:
            self.holding, self.robot_stale = self.bridge.holding, self.robot_data.stale(now_s)
            self.report(now_s)

    def report(self, now_s: float) -> None:
        """A change of what the bridge cannot do, logged and sent at once."""
        errors = self.current_problems(now_s)[0]
        self.diagnostics.facts['command watchdog'] = self.watchdog_fact()
        self.get_logger().warning('; '.join(errors) or 'robot data and commands are back')
        self.diagnostics.publish()

    def watchdog_fact(self) -> str:
        if not self.holding:
            return 'obeying the controller'
        silence = (f'no command for {self.bridge.watchdog.silent_cycles} periods'
                   if self.bridge.commanded else 'no command yet')
        return f'{silence}: holding the load with the static torques of its measured pose'

    def current_problems(self, now_s: float | None = None) -> tuple[list[str], list[str]]:
        now_s = time.monotonic() if now_s is None else now_s
        errors = []
        if self.robot_data.stale(now_s):
            errors.append(f'no joint states from the robot on {self.robot_states_topic} for '
                          f'{self.robot_data.silent_s(now_s):.3f} s')
        if self.holding:
            errors.append(self.watchdog_fact())
        return errors, []


def main(args=None):
    return run(Ros2ControlBridgeNode, args)


if __name__ == '__main__':
    main()
