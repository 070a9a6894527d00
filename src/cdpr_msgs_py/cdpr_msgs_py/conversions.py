"""Message ⇄ numpy conversions with validation: bad input is rejected, never guessed."""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PointStamped, PoseStamped
from rclpy.serialization import deserialize_message
from sensor_msgs.msg import JointState

from .cdr import JointStateCodec, all_finite, cdr_stamp_ns
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


# One codec per joint names: a node's every JointState of the loop has them.
_CODECS: dict[tuple[str, ...], JointStateCodec] = {}


def codec(names: list[str]) -> JointStateCodec:
    key = tuple(names)
    found = _CODECS.get(key)
    if found is None:
        found = _CODECS[key] = JointStateCodec(names)
    return found


def joint_state_bytes(names: list[str], stamp_ns: int, position=(), velocity=(), effort=()) -> bytes:
    """joint_state's message as its CDR bytes (frame ''), laid out without a message object
    (cdr.JointStateCodec): what the loop's nodes publish."""
    return codec(names).encode(stamp_ns, position, velocity, effort)


def joints_from_message(message: JointState | bytes, names: list[str],
                        fields: tuple[str, ...] = ('position', 'velocity', 'effort')) -> Joints:
    """Arrays of the required `fields`, in `names` order; InvalidMessage otherwise. The
    message or its CDR bytes (a raw subscription's, or the loop's inside its process):
    bytes laid out as the loop lays them out are read in place, others deserialised."""
    if isinstance(message, (bytes, bytearray, memoryview)):
        message = bytes(message)
        decoded = codec(names).decode(message)
        if decoded is None:
            try:
                message = deserialize_message(message, JointState)
            except Exception as err:   # rclpy raises its own kinds for bytes it cannot read
                raise InvalidMessage(f'not a JointState: {err}') from None
        else:
            stamp_ns, *tuples = decoded
            for field, values in zip(('position', 'velocity', 'effort'), tuples):
                if field in fields:
                    if len(values) != len(names):
                        raise InvalidMessage(f'{field} has {len(values)} values, expected {len(names)}')
                    if not all_finite(values):
                        raise InvalidMessage(f'{field} holds a non-finite value')
            return Joints(stamp_ns, *(np.array(values, dtype=float) for values in tuples))
    if list(message.name) != names:
        raise InvalidMessage(f'joint names {list(message.name)} differ from {names}')
    arrays = {}
    for field in ('position', 'velocity', 'effort'):
        values = getattr(message, field)
        if field in fields:
            if len(values) != len(names):
                raise InvalidMessage(f'{field} has {len(values)} values, expected {len(names)}')
            if not all_finite(values):
                raise InvalidMessage(f'{field} holds a non-finite value')
        arrays[field] = np.asarray(values, dtype=float)
    return Joints(stamp_to_ns(message.header.stamp), **arrays)


def stamp_of(message) -> int:
    """The header stamp (ns) of a message, or of its CDR bytes (the stamp comes first)."""
    if isinstance(message, (bytes, bytearray, memoryview)):
        try:
            return cdr_stamp_ns(message)
        except (ValueError, struct.error) as err:
            raise InvalidMessage(f'no header stamp: {err}') from None
    return stamp_to_ns(message.header.stamp)


def point_stamped(stamp_ns: int, point, frame_id: str = 'world') -> PointStamped:
    message = PointStamped()
    message.header.stamp = ns_to_stamp(stamp_ns)
    message.header.frame_id = frame_id
    message.point.x, message.point.y, message.point.z = (float(v) for v in point)
    return message


# A point mass's orientation on the pose topics, (w, x, y, z): it has none to tell.
IDENTITY_ORIENTATION = (1.0, 0.0, 0.0, 0.0)
# A unit quaternion on a pose topic may be off unit length by this much.
QUATERNION_NORM_TOLERANCE = 1e-6


def pose_stamped(stamp_ns: int, position, orientation=IDENTITY_ORIENTATION, frame_id: str = 'world') -> PoseStamped:
    """The pose topics' message: position (m) and orientation, a unit quaternion given as
    (w, x, y, z) (ROS orders it x, y, z, w)."""
    message = PoseStamped()
    message.header.stamp = ns_to_stamp(stamp_ns)
    message.header.frame_id = frame_id
    pose = message.pose
    pose.position.x, pose.position.y, pose.position.z = (float(v) for v in position)
    (pose.orientation.w, pose.orientation.x, pose.orientation.y,
     pose.orientation.z) = (float(v) for v in orientation)
    return message


def pose_from_message(message: PoseStamped) -> tuple[np.ndarray, np.ndarray]:
    """(position m, orientation (w, x, y, z)); InvalidMessage for a non-finite value or an
    orientation that is not a unit quaternion."""
    position, orientation = message.pose.position, message.pose.orientation
    values = (position.x, position.y, position.z, orientation.w, orientation.x, orientation.y, orientation.z)
    if not all_finite(values):
        raise InvalidMessage('pose holds a non-finite value')
    if abs(sum(v * v for v in values[3:]) - 1.0) > QUATERNION_NORM_TOLERANCE:
        raise InvalidMessage('orientation is not a unit quaternion')
    return np.array(values[:3]), np.array(values[3:])


def point_from_message(message: PointStamped) -> np.ndarray:
    values = (message.point.x, message.point.y, message.point.z)
    if not all_finite(values):
        raise InvalidMessage('point holds a non-finite value')
    return np.array(values)
