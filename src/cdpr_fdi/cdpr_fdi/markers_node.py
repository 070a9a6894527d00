"""markers: the run for RViz and Foxglove on /cdpr/markers (visualization_msgs/MarkerArray,
frame `world`), `markers.rate_hz` times a second of wall-clock time.

It reads what it draws and nothing more (joint_states, twin/pose, fdi/broken_cable,
recovery/reference), takes no part in the start handshake and runs at background
priority in realtime: the loop never waits for it. The shapes are cdpr_fdi.markers'.
"""
from __future__ import annotations

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Vector3
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Header, Int32
from visualization_msgs.msg import Marker, MarkerArray

from cdpr_control.settings import node_settings
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import InvalidMessage, ns_to_stamp, pose_from_message
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run
from cdpr_msgs_py.stamps import NANOSECONDS

from .config import settled_fdi
from .markers import FRAME_ID, Frame, MarkerStyle, Shape


def marker(shape: Shape, header: Header) -> Marker:
    """One shape as a Marker whose points are in `header`'s frame (identity pose)."""
    return Marker(
        header=header, ns=shape.namespace, id=shape.id, type=getattr(Marker, shape.kind),
        action=Marker.ADD, pose=Pose(orientation=Quaternion(w=1.0)),
        scale=Vector3(x=shape.scale_m, y=shape.scale_m, z=shape.scale_m),
        color=ColorRGBA(**dict(zip('rgba', map(float, shape.colours[0])))),
        lifetime=Duration(),
        points=[Point(x=float(x), y=float(y), z=float(z)) for x, y, z in shape.points_m],
        colors=[ColorRGBA(r=float(r), g=float(g), b=float(b), a=float(a))
                for r, g, b, a in shape.colours])


def marker_array(shapes: list[Shape], stamp_ns: int) -> MarkerArray:
    """A frame: DELETEALL first, so that what a frame no longer has (a cable now broken, an
    end-effector not found) does not linger in the viewer, then every shape."""
    header = Header(stamp=ns_to_stamp(stamp_ns), frame_id=FRAME_ID)
    return MarkerArray(markers=[Marker(header=header, action=Marker.DELETEALL)]
                       + [marker(shape, header) for shape in shapes])


class MarkersNode(CdprNode):

    def __init__(self):
        super().__init__(contract.MARKERS_NODE)
        settings = node_settings(self, contract.MARKERS_NODE)
        self.robot = settings.robot
        fdi, recovery = settled_fdi(settings, self.robot)
        style = MarkerStyle.from_section(settings.section('markers'))
        self.frame = Frame(self.robot, fdi.friction, recovery, style)
        self.names = contract.joint_names(self.robot.cable_count)
        self.stamp_ns: int | None = None
        self.markers = self.create_publisher(MarkerArray, contract.MARKERS,
                                             qos.of_readers(contract.MARKERS))
        self.create_subscription(JointState, contract.JOINT_STATES, self.on_state,
                                 qos.of_readers(contract.JOINT_STATES))
        self.create_subscription(PoseStamped, contract.TWIN_POSE, self.on_twin_pose,
                                 qos.of_readers(contract.TWIN_POSE))
        self.create_subscription(Int32, contract.FDI_BROKEN_CABLE, self.on_broken_cable,
                                 qos.of_readers(contract.FDI_BROKEN_CABLE))
        self.create_subscription(JointState, contract.RECOVERY_REFERENCE, self.on_recovery_reference,
                                 qos.of_readers(contract.RECOVERY_REFERENCE))
        self.create_timer(1.0 / style.rate_hz, self.publish_frame)
        settings.declare(self)

    def on_state(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.JOINT_STATES)
        if joints is None:
            return
        self.stamp_ns = joints.stamp_ns
        self.frame.on_state(joints.stamp_ns / NANOSECONDS, joints.position, joints.velocity,
                            joints.effort)

    def on_twin_pose(self, message: PoseStamped) -> None:
        try:
            self.frame.on_twin_pose(pose_from_message(message)[0])
        except InvalidMessage as err:
            self.diagnostics.reject(contract.TWIN_POSE, str(err))

    def on_broken_cable(self, message: Int32) -> None:
        if not 0 <= message.data <= self.robot.cable_count:
            self.diagnostics.reject(contract.FDI_BROKEN_CABLE, f'no cable {message.data}')
            return
        self.frame.on_broken_cable(message.data)

    def on_recovery_reference(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.RECOVERY_REFERENCE, ('position',))
        if joints is not None:
            self.frame.on_recovery_reference(joints.position)

    def publish_frame(self) -> None:
        if self.stamp_ns is None:
            return
        self.markers.publish(marker_array(self.frame.shapes(), self.stamp_ns))
        self.diagnostics.count('frames')


def main(args=None):
    return run(MarkersNode, args)


if __name__ == '__main__':
    main()
