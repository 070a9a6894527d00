"""digital_twin: the healthy model and its own controller, fed /cdpr/reference only;
/cdpr/twin/joint_states every tick, /cdpr/twin/pose on the view ticks."""
from __future__ import annotations

import numpy as np
from geometry_msgs.msg import PoseStamped
from sensor_msgs.msg import JointState

from cdpr_control.control.controller import JointReference, PdGains
from cdpr_control.model.friction import FrictionModel
from cdpr_control.setup.settings import node_settings
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import joint_state_bytes, pose_stamped
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run

from cdpr_twin.models.twin import DigitalTwin


class DigitalTwinNode(CdprNode):

    def __init__(self):
        super().__init__(contract.DIGITAL_TWIN)
        settings = node_settings(self, contract.DIGITAL_TWIN)
        self.robot, self.period_s, self.period_ns = settings.robot, settings.period_s, settings.period_ns
        control = settings.section('control')
        self.stale_cycles = control.integer('stale_cycles', minimum=1)
        self.gains = PdGains.from_section(self.robot, control)
        self.substeps = settings.section('twin').integer('substeps', minimum=1)
        self.friction = FrictionModel.of_twin(settings.section('twin'), control)
        self.names = contract.joint_names(self.robot.cable_count)
        self.twin: DigitalTwin | None = None   # built at the first reference, where it starts
        DigitalTwin.load_kernels(self.robot)
        self.last_stamp_ns: int | None = None
        self.last_reference: JointReference | None = None
        self.joints = self.create_stream_publisher(JointState, contract.TWIN_JOINT_STATES)
        self.pose = self.create_stream_publisher(PoseStamped, contract.TWIN_POSE)
        # The twin's tick is the reference: it listens once its outputs have listeners.
        self.start_when_matched(lambda: self.create_subscription(
            JointState, contract.REFERENCE, self.on_reference, qos.STREAM))
        settings.declare(self)

    def on_reference(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.REFERENCE)
        if joints is None:
            return
        if self.last_stamp_ns is not None and joints.stamp_ns <= self.last_stamp_ns:
            self.diagnostics.reject(contract.REFERENCE, 'stamp not after the previous one')
            return
        missed = (0 if self.last_stamp_ns is None
                  else (joints.stamp_ns - self.last_stamp_ns) // self.period_ns - 1)
        self.last_stamp_ns = joints.stamp_ns
        if self.twin is not None and missed > 0:
            # Realtime: the controller answered the ticks that got no reference with the last
            # one it had; so does the twin, to stay on the robot's clock (a controller left
            # without references for stale_cycles holds, and so the twin stops following).
            self.diagnostics.count('reference gaps')
            for _ in range(min(missed, self.stale_cycles)):
                self.twin.step(self.last_reference, self.period_s)
        if self.twin is None:
            # The twin starts where the reference starts, at rest.
            try:
                start, orientation = self.robot.body.pose_of_angles(self.robot, joints.position)
                self.twin = DigitalTwin(self.robot, self.gains, start, self.substeps, orientation, self.friction)
            except (ValueError, np.linalg.LinAlgError) as err:
                self.diagnostics.reject(contract.REFERENCE, f'no pose to start the twin from: {err}')
                return
        self.last_reference = JointReference(joints.position, joints.velocity, joints.effort)
        output = self.twin.step(self.last_reference, self.period_s)
        self.joints.publish(joint_state_bytes(self.names, joints.stamp_ns, output.angle_rad,
                                        output.angular_velocity_rad_s, output.torque_nm))
        if self.view_ticks.at(joints.stamp_ns):
            # a view topic: for the markers, the recorder and viewers only (contract.Topic.on_demand)
            self.pose.publish_if_subscribed(lambda: pose_stamped(joints.stamp_ns, output.position_m,
                                                                 output.orientation))
        self.diagnostics.count('ticks')


def main(args=None):
    return run(DigitalTwinNode, args)


if __name__ == '__main__':
    main()
