"""controller: PD + feed-forward on /cdpr/joint_states; the writer of /cdpr/effort_command
(the only one the plant and the supervisor obey: cdpr_msgs_py.sole_writer).

Lockstep: the state of tick k is answered with the reference of exactly tick k (or, in
recovery, the supervisor's setpoint of tick k); with `wait_for_supervisor` also only
after the supervisor's residual of tick k − VERDICT_DELAY_TICKS, and a verdict (the
broken cable, the mode, which carry no stamp) applies from the tick its residual names +
VERDICT_DELAY_TICKS, as in the in-process engine: the twin and the supervisor run a tick
behind the loop. Realtime: the latest of each, never waiting; a verdict applies at once.
"""
from __future__ import annotations

import time

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Int32, String

from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.contract import NOMINAL, SAFE_HOLD
from cdpr_msgs_py.conversions import joint_state_bytes
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run
from cdpr_msgs_py.stamps import NANOSECONDS

from cdpr_control.control.controller import JointController, JointReference, PdGains, command_lead_periods
from cdpr_control.model.friction import FrictionModel
from cdpr_control.setup.settings import node_settings
from cdpr_control.control.setpoints import Setpoints

class ControllerNode(CdprNode):

    def __init__(self):
        super().__init__(contract.CONTROLLER)
        settings = node_settings(self, contract.CONTROLLER)
        self.robot, self.period_ns = settings.robot, settings.period_ns
        control = settings.section('control')
        self.stale_ns = control.integer('stale_cycles', minimum=1) * self.period_ns
        self.last_state_at: float | None = None
        self.controller = JointController(
            self.robot, PdGains.from_section(self.robot, control), FrictionModel.of_robot(self.robot, control),
            command_lead_periods(control.number('drive_delay_s', 0.0, non_negative=True),
                                 control.number('period_s', positive=True)))
        self.setpoints = Setpoints(self.controller, exact=self.clock_mode == 'lockstep',
                                   stale_ns=self.stale_ns)
        self.wait_for_supervisor = self.parameter(
            'wait_for_supervisor', False,
            "lockstep: answer a state only after the supervisor's residual of the tick before")
        self.names = contract.joint_names(self.robot.cable_count)
        self.verdict_ns: int | None = None
        self.delay_ns = contract.VERDICT_DELAY_TICKS * self.period_ns
        # lockstep: the verdict heard since the last residual (broken cables, mode), due
        # from that residual's tick + VERDICT_DELAY_TICKS
        self.heard_cables: list[int] = []
        self.heard_mode: str | None = None
        self.first_state_ns: int | None = None
        self.pending = None
        self.answered: dict[int, np.ndarray] = {}
        self.publisher = self.create_stream_publisher(JointState, contract.EFFORT_COMMAND)
        self.create_subscription(JointState, contract.REFERENCE, self.on_reference, qos.STREAM)
        self.create_subscription(Int32, contract.FDI_BROKEN_CABLE, self.on_broken_cable, qos.LATCHED)
        self.create_subscription(String, contract.MODE, self.on_mode, qos.LATCHED)
        self.create_subscription(JointState, contract.RECOVERY_TENSIONS, self.on_tensions, qos.STREAM)
        self.create_subscription(JointState, contract.RECOVERY_REFERENCE, self.on_recovery_reference,
                                 qos.STREAM)
        if self.wait_for_supervisor and self.clock_mode == 'lockstep':
            # the residual only paces lockstep; in realtime it would cost a third of the loop
            self.create_subscription(JointState, contract.FDI_RESIDUAL, self.on_residual, qos.STREAM)
        self.start_when_matched(lambda: self.create_subscription(
            JointState, contract.JOINT_STATES, self.on_state, qos.STREAM))
        settings.declare(self)

    def on_reference(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.REFERENCE)
        if joints is not None:
            self.setpoints.put_reference(joints.stamp_ns, JointReference(
                joints.position, joints.velocity, joints.effort))
            self.retry()

    def on_recovery_reference(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.RECOVERY_REFERENCE)
        if joints is not None:
            self.setpoints.put_recovery_reference(joints.stamp_ns, JointReference(
                joints.position, joints.velocity, joints.effort))
            self.retry()

    def on_tensions(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.RECOVERY_TENSIONS, ('effort',))
        if joints is not None:
            self.setpoints.put_recovery_tensions(joints.stamp_ns, joints.effort)
            self.retry()

    def on_residual(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.FDI_RESIDUAL, ('effort',))
        if joints is not None:
            self.verdict_ns = (joints.stamp_ns if self.verdict_ns is None
                               else max(joints.stamp_ns, self.verdict_ns))
            if self.heard_cables or self.heard_mode is not None:
                self.setpoints.verdict(joints.stamp_ns + self.delay_ns, self.heard_cables, self.heard_mode)
                self.heard_cables, self.heard_mode = [], None
            self.retry()

    @property
    def verdicts_by_tick(self) -> bool:
        """Lockstep with a supervisor: a verdict waits for the residual that names its tick."""
        return self.wait_for_supervisor and self.clock_mode == 'lockstep'

    def on_state(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.JOINT_STATES, ('position', 'velocity'))
        if joints is None:
            return
        if self.first_state_ns is None:
            self.first_state_ns = joints.stamp_ns
        self.last_state_at = time.monotonic()
        self.diagnostics.count('states')
        self.answer(joints)

    def retry(self) -> None:
        if self.pending is not None:
            self.answer(self.pending)

    def verdict_arrived(self, stamp_ns: int) -> bool:
        """Lockstep with a supervisor: its verdict due on this tick (of the tick
        VERDICT_DELAY_TICKS before) is in."""
        if not self.verdicts_by_tick:
            return True
        if stamp_ns - self.delay_ns < self.first_state_ns:
            return True
        return self.verdict_ns is not None and self.verdict_ns >= stamp_ns - self.delay_ns

    def report_safe_hold(self) -> None:
        """At once, as ERROR, on /diagnostics and (once: Diagnostics logs an episode's
        start) on the console."""
        self.diagnostics.error = f'SAFE_HOLD: {self.setpoints.safe_hold_reason}'
        self.diagnostics.publish()

    def idle(self) -> None:
        super().idle()
        if (self.clock_mode == 'realtime' and self.last_state_at is not None
                and time.monotonic() - self.last_state_at > self.stale_ns / NANOSECONDS
                and self.setpoints.go_safe_hold(
                    f'no joint states for {time.monotonic() - self.last_state_at:.3f} s')):
            self.report_safe_hold()

    def answer(self, joints) -> None:
        if joints.stamp_ns in self.answered:
            torque = self.answered[joints.stamp_ns]
        else:
            if not self.verdict_arrived(joints.stamp_ns):
                self.pending = joints
                return
            mode = self.controller.mode
            torque = self.setpoints.command(joints.stamp_ns, joints.position, joints.velocity)
            if mode == NOMINAL and self.controller.mode == SAFE_HOLD:
                self.report_safe_hold()
            if torque is None:
                self.pending = joints
                return
            self.answered = {joints.stamp_ns: torque}
        self.pending = None
        if not np.all(np.isfinite(torque)):
            # absurd inputs overflowed the PD: send nothing; the drive holds, then brakes
            self.diagnostics.reject(contract.JOINT_STATES, 'the command would not be finite')
            return
        torque = torque.copy()
        torque[self.controller.broken] = 0.0   # also on a command answered before the break
        self.publisher.publish(joint_state_bytes(self.names, joints.stamp_ns, effort=torque))
        self.diagnostics.count('commands')

    def on_broken_cable(self, message: Int32) -> None:
        if not 0 <= message.data <= self.robot.cable_count:
            self.diagnostics.reject(contract.FDI_BROKEN_CABLE, f'cable {message.data} out of range')
            return
        if not message.data:
            return
        if self.verdicts_by_tick:
            self.heard_cables.append(message.data)
        else:
            self.setpoints.cable_broken(message.data)

    def on_mode(self, message: String) -> None:
        try:
            JointController.check_mode(message.data)
        except ValueError as err:
            self.diagnostics.reject(contract.MODE, str(err))
            return
        if self.verdicts_by_tick:
            self.heard_mode = message.data
            return
        self.setpoints.set_mode(message.data)
        self.answered = {}   # a state sent again is answered in the new mode


def main(args=None):
    return run(ControllerNode, args)


if __name__ == '__main__':
    main()
