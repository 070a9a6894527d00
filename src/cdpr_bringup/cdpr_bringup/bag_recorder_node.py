"""bag_recorder: every /cdpr topic (or the `topics` parameter) into a rosbag2 bag via rosbags.

Messages are taken serialized (no decode/encode on the way) and written with their
message definitions, MCAP storage by default (`storage: sqlite3` on request).
"""
from __future__ import annotations

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import PointStamped
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState
from std_msgs.msg import Int32, String

from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.runtime import CdprNode, run

# topic (relative to the namespace unless absolute) → message class
RECORDED = {
    contract.JOINT_STATES: JointState,
    contract.REFERENCE: JointState,
    contract.REFERENCE_POSE: PointStamped,
    contract.GOAL: PointStamped,
    contract.EFFORT_COMMAND: JointState,
    contract.TWIN_JOINT_STATES: JointState,
    contract.TWIN_POSE: PointStamped,
    contract.FDI_RESIDUAL: JointState,
    contract.FDI_BROKEN_CABLE: Int32,
    contract.MODE: String,
    contract.RECOVERY_TENSIONS: JointState,
    contract.RECOVERY_REFERENCE: JointState,
    contract.GROUND_TRUTH_POSE: PointStamped,
    contract.GROUND_TRUTH_TENSIONS: JointState,
    contract.INJECT_FAILURE: Int32,
    contract.CLOCK: Clock,
    contract.DIAGNOSTICS: DiagnosticArray,
}
STORAGES = {'mcap': StoragePlugin.MCAP, 'sqlite3': StoragePlugin.SQLITE3}


def type_name(message_class) -> str:
    module = message_class.__module__.split('.')[0]
    return f'{module}/msg/{message_class.__name__}'


class BagRecorderNode(CdprNode):

    def __init__(self):
        super().__init__('bag_recorder')
        path = self.parameter('bag_path', 'bag')
        storage = self.parameter('storage', 'mcap')
        if storage not in STORAGES:
            raise ValueError(f'parameter storage must be one of {", ".join(STORAGES)}, got {storage!r}')
        topics = self.parameter('topics', list(RECORDED))
        unknown = [t for t in topics if t not in RECORDED]
        if unknown:
            raise ValueError(f'parameter topics: cannot record {unknown}; known: {list(RECORDED)}')
        typestore = get_typestore(Stores.ROS2_KILTED)
        self.writer = Writer(path, version=9, storage_plugin=STORAGES[storage])
        self.writer.open()
        self.recorded = 0
        namespace = self.get_namespace().rstrip('/')
        for topic in topics:
            name = topic if topic.startswith('/') else f'{namespace}/{topic}'
            message_class = RECORDED[topic]
            connection = self.writer.add_connection(name, type_name(message_class), typestore=typestore)
            profile = qos.LATCHED if topic in contract.LATCHED_TOPICS else (
                qos.DIAGNOSTICS if topic == contract.DIAGNOSTICS else qos.STREAM)
            self.create_subscription(message_class, name, self.writer_for(connection), profile, raw=True)
        self.get_logger().info(f'recording {len(topics)} topics into {path} ({storage})')

    def writer_for(self, connection):
        def write(data: bytes) -> None:
            self.writer.write(connection, self.get_clock().now().nanoseconds, data)
            self.recorded += 1
            self.diagnostics.count('messages')
        return write

    def close(self) -> None:
        super().close()
        self.writer.close()
        self.get_logger().info(f'bag closed with {self.recorded} messages')


def main(args=None):
    return run(BagRecorderNode, args)


if __name__ == '__main__':
    main()
