"""A ROS user's own reader of the per-cycle topics: plain rclpy and message packages,
nothing else of this project (for the tests and `cdpr-bench recorder`).

Usage: python -m cdpr_bringup.graph.outside_reader NAMESPACE TIMEOUT_S TOPIC… (relative to
NAMESPACE unless absolute). Subscribes to each TOPIC reliable and keep-all, as a recorder
of one's own would; prints one line `receiving` once every TOPIC has brought a message (so
each writer has matched it), then reads until the timeout; `heard TOPIC` goes to stderr
at each TOPIC's first message. Suspended (SIGSTOP, Ctrl-Z) it
is a reader that stops acknowledging.
"""
import sys
import time

import rclpy
from geometry_msgs.msg import PoseStamped
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

TYPES = {'/clock': Clock, 'reference/pose': PoseStamped, 'twin/pose': PoseStamped,
         'ground_truth/pose': PoseStamped}


def main():
    namespace, timeout_s, topics = sys.argv[1], float(sys.argv[2]), sys.argv[3:]
    rclpy.init()
    node = rclpy.create_node('outside_reader')
    keep_all = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE)
    heard = set()

    def first(topic):
        if topic not in heard:
            heard.add(topic)
            print(f'heard {topic}', file=sys.stderr, flush=True)

    for topic in topics:
        name = topic if topic.startswith('/') else f'{namespace}/{topic}'
        node.create_subscription(TYPES.get(topic, JointState), name,
                                 lambda _message, t=topic: first(t), keep_all)
    deadline = time.monotonic() + timeout_s
    said = False
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
        if not said and heard == set(topics):
            print('receiving', flush=True)
            said = True
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
