"""Reading a bag of the graph back into a Recording (arrays per control tick)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from .engine import Recording

NANOSECONDS = 1e9


def read_topics(bag: str | Path, topics: list[str]) -> dict[str, dict[int, object]]:
    """Per topic, the last message of each header stamp (ns); resent ticks count once."""
    typestore = get_typestore(Stores.ROS2_KILTED)
    found: dict[str, dict[int, object]] = {topic: {} for topic in topics}
    with Reader(bag) as reader:
        connections = [c for c in reader.connections if c.topic in found]
        for connection, _, data in reader.messages(connections=connections):
            message = typestore.deserialize_cdr(data, connection.msgtype)
            stamp = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
            found[connection.topic][stamp] = message
    return found


def recording_from_bag(bag: str | Path, namespace: str = '/cdpr') -> Recording:
    """The Recording of a lockstep or realtime run, on the ticks of /cdpr/joint_states."""
    names = {key: f'{namespace}/{key}' for key in (
        'joint_states', 'effort_command', 'twin/joint_states', 'twin/pose', 'reference',
        'reference/pose', 'ground_truth/pose', 'ground_truth/tensions')}
    found = read_topics(bag, list(names.values()))
    state = found[names['joint_states']]
    stamps = sorted(s for s in state if s in found[names['effort_command']]
                    and s in found[names['twin/joint_states']])
    if not stamps:
        raise ValueError(f'{bag}: no tick has a state, a command and a twin state')

    def joints(key, field):
        return np.array([getattr(found[names[key]][s], field) for s in stamps])

    def points(key):
        return np.array([[p.point.x, p.point.y, p.point.z] for p in
                         (found[names[key]][s] for s in stamps)])

    return Recording(
        time_s=np.array(stamps) / NANOSECONDS,
        angle_rad=joints('joint_states', 'position'),
        angular_velocity_rad_s=joints('joint_states', 'velocity'),
        command_nm=joints('effort_command', 'effort'),
        twin_angle_rad=joints('twin/joint_states', 'position'),
        twin_angular_velocity_rad_s=joints('twin/joint_states', 'velocity'),
        twin_torque_nm=joints('twin/joint_states', 'effort'),
        twin_position_m=points('twin/pose'),
        reference_position_m=points('reference/pose'),
        reference_angle_rad=joints('reference', 'position'),
        true_position_m=points('ground_truth/pose'),
        true_tension_n=joints('ground_truth/tensions', 'effort'),
    )
