"""The per-tick messages of a bag, serialised all ticks at once: byte for byte what
rosbags' CDR serialiser gives for each message, whatever the names' lengths and the
empty fields (alignment), and read back as the values written."""
from __future__ import annotations

import numpy as np
import pytest

from cdpr_msgs_py import cdr as bulk_cdr
from cdpr_bringup.bags.bag_io import TYPESTORE
from cdpr_msgs_py.stamps import ns_parts

TYPES = TYPESTORE.types
JOINT_STATE, POSE_STAMPED = 'sensor_msgs/msg/JointState', 'geometry_msgs/msg/PoseStamped'


def header(stamp_ns: int):
    sec, nanosec = ns_parts(int(stamp_ns))
    return TYPES['std_msgs/msg/Header'](stamp=TYPES['builtin_interfaces/msg/Time'](sec=sec, nanosec=nanosec),
                                        frame_id='')


def stamps(ticks: int) -> np.ndarray:
    # 2 ms ticks from an odd start, across whole seconds
    return 999_000_001 + 2_000_000 * np.arange(ticks, dtype=np.int64)


@pytest.mark.parametrize('names', [['motor_1', 'motor_2', 'motor_3', 'motor_4'],
                                   ['a', 'bb', 'ccc', 'dddd', 'eeeee', 'ffffff'],
                                   [f'joint_{i}' for i in range(1, 9)]],
                         ids=['paper', 'odd_lengths', 'eight'])
@pytest.mark.parametrize('fields', [('position', 'velocity', 'effort'), ('effort',), ('position',)])
def test_joint_states_are_rosbags_bytes(names, fields):
    rng = np.random.default_rng(len(names))
    ticks, joints = 50, len(names)
    values = {field: rng.normal(size=(ticks, joints)) for field in fields}
    rows = bulk_cdr.joint_states(stamps(ticks), names, **values)
    for k, stamp in enumerate(stamps(ticks)):
        message = TYPES[JOINT_STATE](header=header(stamp), name=names, **{
            field: values[field][k] if field in values else np.zeros(0)
            for field in ('position', 'velocity', 'effort')})
        expected = bytes(TYPESTORE.serialize_cdr(message, JOINT_STATE))
        assert rows[k].tobytes() == expected, f'tick {k}'
        read = TYPESTORE.deserialize_cdr(rows[k].tobytes(), JOINT_STATE)
        for field in fields:
            np.testing.assert_array_equal(getattr(read, field), values[field][k])


@pytest.mark.parametrize('turning', [False, True])
def test_pose_stampeds_are_rosbags_bytes(turning):
    """Positions, and a platform's orientations given (w, x, y, z) or a point mass's
    identity, in ROS's (x, y, z, w) order."""
    rng = np.random.default_rng(3)
    xyz = rng.normal(size=(40, 3))
    wxyz = rng.normal(size=(40, 4)) if turning else None
    rows = bulk_cdr.pose_stampeds(stamps(40), xyz, wxyz)
    for k, stamp in enumerate(stamps(40)):
        w, x, y, z = wxyz[k] if turning else (1.0, 0.0, 0.0, 0.0)
        pose = TYPES['geometry_msgs/msg/Pose'](position=TYPES['geometry_msgs/msg/Point'](*map(float, xyz[k])),
                                               orientation=TYPES['geometry_msgs/msg/Quaternion'](
                                                   x=float(x), y=float(y), z=float(z), w=float(w)))
        message = TYPES[POSE_STAMPED](header=header(stamp), pose=pose)
        assert rows[k].tobytes() == bytes(TYPESTORE.serialize_cdr(message, POSE_STAMPED)), f'tick {k}'


@pytest.mark.parametrize('fields', [('position', 'velocity', 'effort'), ('effort',), ('position', 'velocity')])
def test_a_nodes_joint_state_bytes_are_rclpys_message_and_read_back_either_way(fields):
    """What the loop's nodes publish (cdr.JointStateCodec) is the JointState rclpy reads;
    what rclpy (any other writer) serialises, with whatever its padding holds, reads back
    as the same values; other names or a message cut short are not read (the node then
    deserialises them, and rejects them naming why)."""
    from rclpy.serialization import deserialize_message, serialize_message
    from sensor_msgs.msg import JointState

    from cdpr_msgs_py.cdr import JointStateCodec
    from cdpr_msgs_py.conversions import InvalidMessage, joint_state, joints_from_message
    names = [f'motor_{i}' for i in range(1, 9)]
    rng = np.random.default_rng(3)
    values = {field: rng.normal(size=8) for field in fields}
    stamp = 3 * 10 ** 9 + 2_000_001
    codec = JointStateCodec(names)
    ours = codec.encode(stamp, **values)
    message = deserialize_message(ours, JointState)
    assert list(message.name) == names and stamp_of_message(message) == stamp
    theirs = serialize_message(joint_state(names, stamp, **values))
    for data in (ours, theirs):
        decoded = codec.decode(data)
        assert decoded[0] == stamp
        for field, got in zip(('position', 'velocity', 'effort'), decoded[1:]):
            assert list(got) == (list(values[field]) if field in values else [])
    assert JointStateCodec(names[::-1]).decode(ours) is None and codec.decode(ours[:40]) is None
    joints = joints_from_message(JointStateCodec(names[:4]).encode(stamp, effort=np.ones(4)), names[:4], ('effort',))
    assert joints.stamp_ns == stamp and list(joints.effort) == [1.0] * 4
    with pytest.raises(InvalidMessage, match='non-finite'):
        joints_from_message(JointStateCodec(names[:4]).encode(stamp, effort=[1.0, np.nan, 0.0, 0.0]), names[:4],
                            ('effort',))
    with pytest.raises(InvalidMessage, match='joint names'):
        joints_from_message(ours, names[::-1])


def stamp_of_message(message) -> int:
    return message.header.stamp.sec * 10 ** 9 + message.header.stamp.nanosec
