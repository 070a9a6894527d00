"""controller: PD + feed-forward on /cdpr/joint_states; the only writer of /cdpr/effort_command."""
from __future__ import annotations

from collections import OrderedDict

import numpy as np
from sensor_msgs.msg import JointState
from std_msgs.msg import Int32, String

from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import joint_state
from cdpr_msgs_py.runtime import CdprNode, run

from .config import load_section, resolve_config
from .controller import JointController, JointReference, PdGains
from .robot import load_robot

REFERENCE_BUFFER = 256


class ControllerNode(CdprNode):

    def __init__(self):
        super().__init__('controller')
        config = resolve_config(self.get_parameter('config_file').value)
        self.robot = load_robot(config)
        self.controller = JointController(self.robot, PdGains.from_section(
            self.robot, load_section(config, 'control')))
        self.names = contract.joint_names(self.robot.cable_count)
        self.references: OrderedDict[int, JointReference] = OrderedDict()
        self.pending = None
        self.answered: dict[int, np.ndarray] = {}
        self.publisher = self.create_publisher(JointState, contract.EFFORT_COMMAND, qos.STREAM)
        self.create_subscription(JointState, contract.JOINT_STATES, self.on_state, qos.STREAM)
        self.create_subscription(JointState, contract.REFERENCE, self.on_reference, qos.STREAM)
        self.create_subscription(Int32, contract.FDI_BROKEN_CABLE, self.on_broken_cable, qos.LATCHED)
        self.create_subscription(String, contract.MODE, self.on_mode, qos.LATCHED)
        self.create_subscription(JointState, contract.RECOVERY_TENSIONS, self.on_tensions, qos.STREAM)

    def on_reference(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.REFERENCE)
        if joints is None:
            return
        self.references[joints.stamp_ns] = JointReference(joints.position, joints.velocity,
                                                          joints.effort)
        while len(self.references) > REFERENCE_BUFFER:
            self.references.popitem(last=False)
        if self.pending is not None:
            self.answer(self.pending)

    def on_state(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.JOINT_STATES, ('position', 'velocity'))
        if joints is None:
            return
        self.diagnostics.count('states')
        self.answer(joints)

    def reference_for(self, stamp_ns: int) -> JointReference | None:
        """Lockstep: the reference of exactly this tick. Realtime: the latest not after it."""
        if self.clock_mode == 'lockstep':
            return self.references.get(stamp_ns)
        earlier = [stamp for stamp in self.references if stamp <= stamp_ns]
        return self.references[max(earlier)] if earlier else None

    def answer(self, joints) -> None:
        if joints.stamp_ns in self.answered:
            torque = self.answered[joints.stamp_ns]
        else:
            reference = self.reference_for(joints.stamp_ns)
            if reference is None and self.controller.mode == 'NOMINAL':
                self.pending = joints
                return
            torque = self.controller.command(joints.position, joints.velocity, reference)
            self.answered = {joints.stamp_ns: torque}
        self.pending = None
        self.publisher.publish(joint_state(self.names, joints.stamp_ns, effort=torque))
        self.diagnostics.count('commands')

    def on_broken_cable(self, message: Int32) -> None:
        if not 0 <= message.data <= self.robot.cable_count:
            self.diagnostics.reject(contract.FDI_BROKEN_CABLE, f'cable {message.data} out of range')
            return
        if message.data:
            self.controller.set_broken([message.data - 1])

    def on_mode(self, message: String) -> None:
        try:
            self.controller.set_mode(message.data)
        except ValueError as err:
            self.diagnostics.reject(contract.MODE, str(err))

    def on_tensions(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.RECOVERY_TENSIONS, ('effort',))
        if joints is None:
            return
        self.controller.set_tension_setpoint(joints.effort)


def main(args=None):
    return run(ControllerNode, args)


if __name__ == '__main__':
    main()
