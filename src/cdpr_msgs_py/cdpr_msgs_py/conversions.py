"""Message ⇄ numpy conversions with validation: bad input is rejected, never guessed."""
from __future__ import annotations

from dataclasses import dataclass
from math import isfinite

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped
from sensor_msgs.msg import JointState

from .stamps import ns_parts, stamp_to_ns


class InvalidMessage(ValueError):
    """A message that must not reach the core (wrong size, names, NaN)."""


@dataclass
class Joints:
    """One JointState as arrays: stamp (ns), θ (rad), θ̇ (rad/s), effort (N·m or N)."""

    stamp_ns: int
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


def ns_to_stamp(stamp_ns: int) -> Time:
    sec, nanosec = ns_parts(stamp_ns)
    return Time(sec=sec, nanosec=nanosec)


def joint_state(names: list[str], stamp_ns: int, position=(), velocity=(), effort=(),
                frame_id: str = '') -> JointState:
    message = JointState()
    message.header.stamp = ns_to_stamp(stamp_ns)
    message.header.frame_id = frame_id
    message.name = names
    message.position = np.asarray(position, dtype=float).tolist()
    message.velocity = np.asarray(velocity, dtype=float).tolist()
    message.effort = np.asarray(effort, dtype=float).tolist()
    return message


def joints_from_message(message: JointState, names: list[str],
                        fields: tuple[str, ...] = ('position', 'velocity', 'effort')) -> Joints:
    """Arrays of the required `fields`, in `names` order; InvalidMessage otherwise."""
    if list(message.name) != names:
        raise InvalidMessage(f'joint names {list(message.name)} differ from {names}')
    arrays = {}
    for field in ('position', 'velocity', 'effort'):
        values = getattr(message, field)
        if field in fields:
            if len(values) != len(names):
                raise InvalidMessage(f'{field} has {len(values)} values, expected {len(names)}')
            # math.isfinite per value: np.isfinite and np.all cost ~3 µs a field on m values
            if not all(map(isfinite, values)):
                raise InvalidMessage(f'{field} holds a non-finite value')
        arrays[field] = np.asarray(values, dtype=float)
    return Joints(stamp_to_ns(message.header.stamp), **arrays)


def point_stamped(stamp_ns: int, point, frame_id: str = 'world') -> PointStamped:
    message = PointStamped()
    message.header.stamp = ns_to_stamp(stamp_ns)
    message.header.frame_id = frame_id
    message.point.x, message.point.y, message.point.z = (float(v) for v in point)
    return message


def point_from_message(message: PointStamped) -> np.ndarray:
    values = (message.point.x, message.point.y, message.point.z)
    if not all(map(isfinite, values)):   # as joints_from_message: np.isfinite costs more
        raise InvalidMessage('point holds a non-finite value')
    return np.array(values)
