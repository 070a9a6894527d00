"""The topic table of cdpr_msgs_py.contract and what is derived from it: the graph's
start handshake, the recorder's topics, and the table of docs/design.md §3."""
from __future__ import annotations

import itertools

import pytest

from cdpr_bringup.graph import graph_nodes

# The `matches` of each node (package/executable, in start order), as graph_nodes()
# computed them when the handshake was still written out by hand, per
# (supervised, plant, bag, clock_mode). Sorted and space-joined: a node waits for all its
# entries, so their order means nothing.
PINNED = {
    (True, True, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': (
            'publisher:effort_command=2 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_twin/plant_simulator': 'publisher:joint_states=3 subscription:effort_command=1',
    },
    (True, True, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_twin/plant_simulator': 'publisher:joint_states=3 subscription:effort_command=1',
    },
    (True, True, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': (
            'publisher:effort_command=3 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=2 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:/clock=1 publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=4 subscription:effort_command=1'),
    },
    (True, True, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': 'publisher:effort_command=3 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=4 subscription:effort_command=1'),
    },
    (True, False, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': (
            'publisher:effort_command=2 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
    },
    (True, False, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1',
        'cdpr_fdi/supervisor': (
            'subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
    },
    (True, False, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': (
            'publisher:effort_command=3 subscription:fdi/residual=1 subscription:reference=1'),
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=2 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
    (True, False, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=4',
        'cdpr_control/controller': 'publisher:effort_command=3 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=2 publisher:twin/pose=1',
        'cdpr_fdi/supervisor': (
            'publisher:fdi/residual=1 subscription:effort_command=1 subscription:reference=1 '
            'subscription:twin/joint_states=1'),
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
    (False, True, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
        'cdpr_twin/plant_simulator': 'publisher:joint_states=2 subscription:effort_command=1',
    },
    (False, True, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
        'cdpr_twin/plant_simulator': 'publisher:joint_states=2 subscription:effort_command=1',
    },
    (False, True, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:/clock=1 publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=3 subscription:effort_command=1'),
    },
    (False, True, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
        'cdpr_twin/plant_simulator': (
            'publisher:ground_truth/pose=1 publisher:ground_truth/tensions=1 '
            'publisher:joint_states=3 subscription:effort_command=1'),
    },
    (False, False, False, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
    },
    (False, False, False, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference=2',
        'cdpr_control/controller': 'publisher:effort_command=1 subscription:reference=1',
        'cdpr_twin/digital_twin': '',
    },
    (False, False, True, 'lockstep'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:/clock=1 subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
    (False, False, True, 'realtime'): {
        'cdpr_control/trajectory_generator': 'publisher:reference/pose=1 publisher:reference=3',
        'cdpr_control/controller': 'publisher:effort_command=2 subscription:reference=1',
        'cdpr_twin/digital_twin': 'publisher:twin/joint_states=1 publisher:twin/pose=1',
        'cdpr_bringup/bag_recorder': (
            'subscription:effort_command=1 subscription:fdi/residual=1 '
            'subscription:ground_truth/pose=1 subscription:ground_truth/tensions=1 '
            'subscription:reference/pose=1 subscription:reference=1 '
            'subscription:twin/joint_states=1 subscription:twin/pose=1'),
    },
}


@pytest.mark.parametrize('supervised, plant, bag, clock_mode',
                         list(itertools.product((True, False), (True, False), (False, True),
                                                ('lockstep', 'realtime'))))
def test_the_start_handshake_is_the_one_written_by_hand(supervised, plant, bag, clock_mode):
    nodes = graph_nodes({'clock_mode': clock_mode}, 'bag' if bag else None,
                        supervised=supervised, plant=plant)
    matches = {f'{node.package}/{node.executable}': ' '.join(sorted(node.parameters['matches']))
               for node in nodes}
    assert matches == PINNED[supervised, plant, bag, clock_mode]
    assert list(matches) == list(PINNED[supervised, plant, bag, clock_mode])
