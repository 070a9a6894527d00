"""Message ⇄ numpy conversions: round trip, and rejection of what must not reach the core."""
from __future__ import annotations

import math

import numpy as np
import pytest

from cdpr_msgs_py.contract import joint_names
from cdpr_msgs_py.conversions import InvalidMessage, joint_state, joints_from_message, pose_from_message, pose_stamped

NAMES = joint_names(4)


def test_round_trip_keeps_stamp_order_and_values():
    message = joint_state(NAMES, 3_000_000_007, [0.1, 0.2, 0.3, 0.4], [1, 2, 3, 4], [-0.5] * 4)
    joints = joints_from_message(message, NAMES)
    assert joints.stamp_ns == 3_000_000_007
    np.testing.assert_array_equal(joints.position, [0.1, 0.2, 0.3, 0.4])
    np.testing.assert_array_equal(joints.velocity, [1.0, 2.0, 3.0, 4.0])
    np.testing.assert_array_equal(joints.effort, [-0.5] * 4)


@pytest.mark.parametrize('bad, match', [
    (dict(position=[0.1, 0.2, 0.3]), 'position has 3 values, expected 4'),
    (dict(velocity=[0.0] * 5), 'velocity has 5 values, expected 4'),
    (dict(effort=[0.0, math.nan, 0.0, 0.0]), 'effort holds a non-finite value'),
    (dict(position=[0.0, 0.0, math.inf, 0.0]), 'position holds a non-finite value'),
    (dict(velocity=[-math.inf, 0.0, 0.0, 0.0]), 'velocity holds a non-finite value'),
])
def test_required_fields_of_wrong_size_or_not_finite_are_rejected(bad, match):
    fields = dict(position=[0.0] * 4, velocity=[0.0] * 4, effort=[0.0] * 4)
    fields.update(bad)
    with pytest.raises(InvalidMessage, match=match):
        joints_from_message(joint_state(NAMES, 0, **fields), NAMES)


def test_wrong_joint_names_are_rejected():
    message = joint_state(['motor_2', 'motor_1', 'motor_3', 'motor_4'], 0, [0.0] * 4, [0.0] * 4,
                          [0.0] * 4)
    with pytest.raises(InvalidMessage, match='joint names'):
        joints_from_message(message, NAMES)


def test_only_the_required_fields_are_checked():
    command = joint_state(NAMES, 5, effort=[0.1, -0.2, 0.3, -0.4])
    joints = joints_from_message(command, NAMES, ('effort',))
    np.testing.assert_array_equal(joints.effort, [0.1, -0.2, 0.3, -0.4])
    assert joints.position.size == 0
    with pytest.raises(InvalidMessage, match='position has 0 values'):
        joints_from_message(command, NAMES)


def test_a_pose_keeps_its_orientation_and_a_bad_one_is_rejected():
    """The pose topics carry (w, x, y, z) in ROS's (x, y, z, w) fields; a point mass's is
    the identity."""
    turned = (np.cos(0.2), 0.0, np.sin(0.2), 0.0)
    position, orientation = pose_from_message(pose_stamped(5, [0.1, 0.2, 0.3], turned))
    assert position.tolist() == [0.1, 0.2, 0.3] and orientation.tolist() == list(turned)
    message = pose_stamped(5, [0.1, 0.2, 0.3])
    assert (message.pose.orientation.w, message.pose.orientation.x) == (1.0, 0.0)
    with pytest.raises(InvalidMessage, match='not a unit quaternion'):
        pose_from_message(pose_stamped(5, [0.1, 0.2, 0.3], (1.0, 0.5, 0.0, 0.0)))
    with pytest.raises(InvalidMessage, match='non-finite'):
        pose_from_message(pose_stamped(5, [np.nan, 0.2, 0.3]))
