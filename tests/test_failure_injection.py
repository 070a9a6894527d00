"""inject_failure breaks a cable only on a plant started with failure injection on, and
only from the node it names (issue 26 item 3): in this process, on the middleware's GIDs.
That a running graph's plant refuses an outside node's injection by default is asserted in
test_outside_nodes.py's graph run."""
from __future__ import annotations

import time

import rclpy
from std_msgs.msg import Int32

from cdpr_msgs_py import contract, qos
from cdpr_msgs_py.runtime.spin import make_executor
from cdpr_twin.nodes.plant_simulator_node import PlantSimulatorNode

from conftest import PAPER_ROBOT

NAMESPACE = '/cdpr_injection_unit'
MATCH_TIMEOUT_S = 10.0


def attempt(parameters: list[str]) -> PlantSimulatorNode:
    """A plant started with `parameters`; an `injector` node asks for cable 3, a `stranger`
    for cable 2. Returns the plant once both messages were handled."""
    rclpy.init(args=['--ros-args', '-r', f'__ns:={NAMESPACE}', '-p', f'config_file:={PAPER_ROBOT}',
                     *parameters])
    nodes, executor = [], make_executor()
    try:
        plant = PlantSimulatorNode()
        senders = {name: rclpy.create_node(name) for name in ('injector', 'stranger')}
        nodes = [plant, *senders.values()]
        publishers = {name: node.create_publisher(Int32, contract.INJECT_FAILURE, qos.STREAM)
                      for name, node in senders.items()}
        for node in nodes:
            executor.add_node(node)
        deadline = time.monotonic() + MATCH_TIMEOUT_S
        while not all(publisher.get_subscription_count() for publisher in publishers.values()):
            assert time.monotonic() < deadline, 'the plant never matched the injectors'
            executor.spin_once(timeout_sec=0.05)
        publishers['stranger'].publish(Int32(data=2))
        publishers['injector'].publish(Int32(data=3))
        while len(plant.plant.broken) + plant.diagnostics.rejected[contract.INJECT_FAILURE] < 2:
            assert time.monotonic() < deadline + MATCH_TIMEOUT_S, 'not every injection arrived'
            executor.spin_once(timeout_sec=0.05)
        return plant
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
        rclpy.shutdown()


def test_a_plant_refuses_every_injection_by_default():
    plant = attempt([])
    assert plant.plant.broken == []
    assert plant.diagnostics.rejected == {contract.INJECT_FAILURE: 2}


def test_with_injection_on_only_the_named_node_breaks_a_cable():
    plant = attempt(['-p', 'failure_injection:=true', '-p', 'injection_writer:=injector'])
    assert plant.plant.broken == [2], 'cable 3, from the injector; nothing from the stranger'
    assert plant.diagnostics.rejected == {contract.INJECT_FAILURE: 1}
