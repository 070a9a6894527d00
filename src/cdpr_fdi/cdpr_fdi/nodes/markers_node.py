"""markers: the run for RViz and Foxglove on /cdpr/markers (visualization_msgs/MarkerArray,
frame `world`), a frame per view tick (streams.view_rate_hz), stamped with it.

It reads the view topics of the tick it draws (ground_truth/pose and /tensions,
twin/pose, reference/pose) and the verdict (fdi/broken_cable), no loop topic; it takes no
part in the start handshake and runs at background priority in realtime: the loop never
waits for it. The shapes are cdpr_fdi.view.markers'.
"""
from __future__ import annotations

from builtin_interfaces.msg import Duration
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Vector3
from sensor_msgs.msg import JointState
from std_msgs.msg import ColorRGBA, Header, Int32
from visualization_msgs.msg import Marker, MarkerArray

from cdpr_control.setup.settings import node_settings
from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.conversions import InvalidMessage, ns_to_stamp, pose_from_message
from cdpr_msgs_py.runtime.node import CdprNode
from cdpr_msgs_py.runtime.spin import run
from cdpr_msgs_py.stamps import stamp_to_ns

from ..settings.config import settled_fdi
from ..view.markers import FRAME_ID, Frame, MarkerStyle, Shape


def marker(shape: Shape, header: Header) -> Marker:
    """One shape as a Marker whose points are in `header`'s frame (identity pose); a colour
    per point only where they differ (Shape.point_colours: building a ColorRGBA per point
    was a third of a frame's time)."""
    r, g, b, a = shape.colours[0].tolist()
    return Marker(
        header=header, ns=shape.namespace, id=shape.id, type=getattr(Marker, shape.kind),
        action=Marker.ADD, pose=Pose(orientation=Quaternion(w=1.0)),
        scale=Vector3(x=shape.scale_m, y=shape.scale_m, z=shape.scale_m),
        color=ColorRGBA(r=r, g=g, b=b, a=a), lifetime=Duration(),
        points=[Point(x=x, y=y, z=z) for x, y, z in shape.points_m.tolist()],
        colors=[ColorRGBA(r=r, g=g, b=b, a=a) for r, g, b, a in shape.point_colours])


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
        _, recovery = settled_fdi(settings, self.robot)
        style = MarkerStyle.from_section(settings.section('markers'))
        ground_truth = self.parameter('ground_truth', True,
                                      'the graph has a plant simulator, whose ground truth is drawn '
                                      '(false beside a hardware bridge: the twin is)')
        self.frame = Frame(self.robot, recovery, style, ground_truth)
        self.names = contract.joint_names(self.robot.cable_count)
        self.markers = self.create_publisher(MarkerArray, contract.MARKERS,
                                             qos.of_readers(contract.MARKERS))
        views = [(contract.TWIN_POSE, 'twin'), (contract.REFERENCE_POSE, 'reference')]
        if ground_truth:
            views.append((contract.GROUND_TRUTH_POSE, 'true_pose'))
            self.create_subscription(JointState, contract.GROUND_TRUTH_TENSIONS, self.on_tensions,
                                     qos.of_readers(contract.GROUND_TRUTH_TENSIONS))
        for topic, name in views:
            self.create_subscription(PoseStamped, topic, lambda message, t=topic, n=name: self.on_pose(t, n, message),
                                     qos.of_readers(topic))
        self.create_subscription(Int32, contract.FDI_BROKEN_CABLE, self.on_broken_cable,
                                 qos.of_readers(contract.FDI_BROKEN_CABLE))
        settings.declare(self)

    def on_pose(self, topic: str, name: str, message: PoseStamped) -> None:
        try:
            pose = pose_from_message(message)
        except InvalidMessage as err:
            self.diagnostics.reject(topic, str(err))
            return
        self.frame.on_view(name, stamp_to_ns(message.header.stamp), pose)
        self.publish_frame()

    def on_tensions(self, message: JointState) -> None:
        joints = self.joints_or_reject(message, contract.GROUND_TRUTH_TENSIONS, ('effort',))
        if joints is not None:
            self.frame.on_view('true_tension', joints.stamp_ns, joints.effort)
            self.publish_frame()

    def on_broken_cable(self, message: Int32) -> None:
        if not 0 <= message.data <= self.robot.cable_count:
            self.diagnostics.reject(contract.FDI_BROKEN_CABLE, f'no cable {message.data}')
            return
        self.frame.on_broken_cable(message.data)

    def publish_frame(self) -> None:
        drawn = self.frame.take()
        if drawn is not None:
            stamp_ns, shapes = drawn
            self.markers.publish(marker_array(shapes, stamp_ns))
            self.diagnostics.count('frames')


def main(args=None):
    return run(MarkersNode, args)


if __name__ == '__main__':
    main()
