"""A node started alone (`ros2 run`, no launcher) lands in /cdpr, and `-r __ns:=…` still
moves it: the namespace is the node's default, not the launcher's doing."""
from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import rclpy
from rclpy.context import Context
from rclpy.node import Node

from conftest import PAPER_ROBOT


def start_twin(*arguments: str) -> subprocess.Popen:
    executable = Path(sys.executable).parent / 'digital_twin'
    return subprocess.Popen([str(executable), '--ros-args', '-p', f'config_file:={PAPER_ROBOT}',
                             *arguments],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def stop(process: subprocess.Popen) -> str:
    process.send_signal(signal.SIGINT)
    try:
        return process.communicate(timeout=15)[1]
    except subprocess.TimeoutExpired:
        process.kill()
        return process.communicate()[1]


@pytest.mark.graph
def test_a_node_started_alone_is_in_cdpr_and_a_remap_moves_it():
    alone, moved = start_twin(), start_twin('-r', '__ns:=/robot2')
    context = Context()
    rclpy.init(args=[], context=context)
    listener = Node('namespace_listener', context=context)
    wanted = {'/cdpr/twin/joint_states', '/robot2/twin/joint_states'}
    wanted_nodes = {'/cdpr/digital_twin', '/robot2/digital_twin'}
    try:
        deadline = time.monotonic() + 60
        while True:
            topics = {name for name, _ in listener.get_topic_names_and_types()}
            nodes = set(listener.get_fully_qualified_node_names())
            if (wanted <= topics and wanted_nodes <= nodes) or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        assert wanted <= topics, sorted(topics)
        assert wanted_nodes <= nodes, sorted(nodes)
        assert not {'/twin/joint_states', '/robot2/cdpr/twin/joint_states'} & topics, sorted(topics)
    finally:
        listener.destroy_node()
        rclpy.shutdown(context=context)
        errors = stop(alone), stop(moved)
    assert (alone.returncode, moved.returncode) == (0, 0), errors
