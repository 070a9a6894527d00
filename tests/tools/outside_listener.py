"""A ROS user's own tool: plain rclpy and message packages, nothing of this project.

Usage: outside_listener.py NAMESPACE TIMEOUT_S. Subscribes to NAMESPACE/joint_states,
NAMESPACE/fdi/broken_cable (reliable, transient local: the contract's QoS) and
/diagnostics; exits once it has seen a state, a diagnostics message and a broken cable,
or at the timeout, printing one JSON line of what it received.
"""
import json
import sys
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState
from std_msgs.msg import Int32


def main():
    namespace, timeout_s = sys.argv[1], float(sys.argv[2])
    rclpy.init()
    node = rclpy.create_node('outside_listener')
    seen = {'joint_states': 0, 'diagnostics': 0, 'broken_cable': []}
    node.create_subscription(JointState, f'{namespace}/joint_states',
                             lambda m: seen.__setitem__('joint_states', seen['joint_states'] + 1), 10)
    node.create_subscription(DiagnosticArray, '/diagnostics',
                             lambda m: seen.__setitem__('diagnostics', seen['diagnostics'] + 1), 10)
    latched = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                         durability=DurabilityPolicy.TRANSIENT_LOCAL)
    node.create_subscription(Int32, f'{namespace}/fdi/broken_cable',
                             lambda m: seen['broken_cable'].append(m.data), latched)
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.05)
        if seen['joint_states'] and seen['diagnostics'] and any(seen['broken_cable']):
            break
    print(json.dumps(seen), flush=True)
    node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
