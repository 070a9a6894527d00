"""Other writers on a graph's motors: plain rclpy and message packages, nothing of this project.

Usage: outside_writer.py NAMESPACE SECONDS MATCH_TIMEOUT_S NODE_NAME [NODE_NAME …]. Makes
one node per NODE_NAME in NAMESPACE, each with a publisher on NAMESPACE/effort_command.
Once every publisher has matched a subscriber (at most MATCH_TIMEOUT_S), answers every
NAMESPACE/joint_states it receives for SECONDS with zero torques on the same joints, from
each node in turn, stamped alternately as that state (as the controller's answer is) and
with a zero stamp (as `ros2 topic pub` sends); the first node also asks, every
INJECT_EVERY states, for cable 1 to break on NAMESPACE/inject_failure (which no plant
started by default obeys). Prints one JSON line: how many commands each node sent, how
many of them carried a state's stamp, and how many injections the first node sent.
"""
import json
import sys
import time

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import (DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy,
                       qos_profile_sensor_data)
from sensor_msgs.msg import JointState
from std_msgs.msg import Int32

# The contract's per-cycle QoS, written out: this tool imports nothing of the project.
STREAM = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                    durability=DurabilityPolicy.VOLATILE)
# A request to break cable 1 goes out with every INJECT_EVERY-th state answered.
INJECT_EVERY = 100


def main():
    namespace, seconds, match_timeout_s = sys.argv[1], float(sys.argv[2]), float(sys.argv[3])
    names = sys.argv[4:]
    rclpy.init()
    executor = SingleThreadedExecutor()
    nodes = [rclpy.create_node(name, namespace=namespace) for name in names]
    publishers = [node.create_publisher(JointState, f'{namespace}/effort_command', STREAM)
                  for node in nodes]
    injector = nodes[0].create_publisher(Int32, f'{namespace}/inject_failure', STREAM)
    for node in nodes:
        executor.add_node(node)
    sent = {name: {'commands': 0, 'copied_stamps': 0} for name in names}
    sent[names[0]]['injections'] = 0
    states = [0]

    def answer(state: JointState) -> None:
        turn = states[0]
        states[0] += 1
        name, publisher = names[turn % len(names)], publishers[turn % len(names)]
        command = JointState(name=list(state.name), effort=[0.0] * len(state.name))
        if (turn // len(names)) % 2 == 0:
            command.header.stamp = state.header.stamp
            sent[name]['copied_stamps'] += 1
        publisher.publish(command)
        sent[name]['commands'] += 1
        if turn % INJECT_EVERY == 0:
            injector.publish(Int32(data=1))
            sent[names[0]]['injections'] += 1

    deadline = time.monotonic() + match_timeout_s
    while not all(p.get_subscription_count() for p in [*publishers, injector]) and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    # Best effort, newest only: a tool that falls behind must not hold back the plant's
    # reliable writer.
    nodes[0].create_subscription(JointState, f'{namespace}/joint_states', answer,
                                 qos_profile_sensor_data)
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    print(json.dumps(sent), flush=True)
    executor.shutdown()
    for node in nodes:
        node.destroy_node()
    rclpy.shutdown()


if __name__ == '__main__':
    main()
