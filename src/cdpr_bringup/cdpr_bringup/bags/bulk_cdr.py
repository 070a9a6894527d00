"""The CDR bytes of a run's per-tick messages, all ticks of a topic at once.

A JointState of a given robot, or a PoseStamped, has the same layout on every tick:
only the stamp and the numbers change. So the bytes of one message are laid out once
(little-endian CDR as ROS 2 serialises it, alignment counted from after the 4-byte
encapsulation header) and the ticks' values are written into a (ticks, bytes) array with
numpy, instead of building and serialising one message object per tick.
`tests/test_bulk_cdr.py` checks the bytes against rosbags' serialiser.
"""
from __future__ import annotations

import numpy as np

from cdpr_msgs_py.stamps import NANOSECONDS

ENCAPSULATION = b'\x00\x01\x00\x00'   # CDR, little endian


class Layout:
    """The bytes of one message being laid out, and where the per-tick values go."""

    def __init__(self):
        self.body = bytearray()
        self.slots: list[tuple[int, np.ndarray]] = []   # (offset in the body, (ticks, n) values)

    def align(self, size: int) -> None:
        self.body += bytes(-len(self.body) % size)

    def uint32(self, value: int) -> None:
        self.align(4)
        self.body += np.uint32(value).tobytes()

    def string(self, text: str) -> None:
        data = text.encode()
        self.uint32(len(data) + 1)
        self.body += data + b'\x00'

    def header(self, stamps_ns: np.ndarray, frame_id: str) -> None:
        """std_msgs/Header: the stamp (int32 s, uint32 ns) of each tick, the frame."""
        self.align(4)
        seconds, nanoseconds = np.divmod(np.asarray(stamps_ns, dtype=np.int64), NANOSECONDS)
        self.slots.append((len(self.body), seconds.astype('<i4')[:, None]))
        self.slots.append((len(self.body) + 4, nanoseconds.astype('<u4')[:, None]))
        self.body += bytes(8)
        self.string(frame_id)

    def doubles(self, values: np.ndarray) -> None:
        """A fixed number of float64 (each tick's row of `values`)."""
        values = np.asarray(values, dtype='<f8')
        if values.shape[1]:
            self.align(8)
            self.slots.append((len(self.body), values))
            self.body += bytes(8 * values.shape[1])

    def double_sequence(self, values: np.ndarray | None, ticks: int) -> None:
        """float64[]: each tick's row of `values` (None: empty on every tick)."""
        values = np.zeros((ticks, 0)) if values is None else values
        self.uint32(values.shape[1])
        self.doubles(values)

    def messages(self) -> np.ndarray:
        """(ticks, bytes) uint8: row k is the serialised message of tick k."""
        ticks = len(self.slots[0][1])
        rows = np.tile(np.frombuffer(ENCAPSULATION + bytes(self.body), dtype=np.uint8), (ticks, 1))
        start = len(ENCAPSULATION)
        for offset, values in self.slots:
            width = values.dtype.itemsize * values.shape[1]
            rows[:, start + offset:start + offset + width] = \
                np.ascontiguousarray(values).view(np.uint8).reshape(ticks, width)
        return rows


def joint_states(stamps_ns: np.ndarray, names: list[str], position=None, velocity=None,
                 effort=None) -> np.ndarray:
    """sensor_msgs/JointState of every tick (stamps in ns; each array (ticks, joints) or
    None for an empty field), frame ''."""
    layout = Layout()
    layout.header(stamps_ns, '')
    layout.uint32(len(names))
    for name in names:
        layout.string(name)
    for values in (position, velocity, effort):
        layout.double_sequence(values, len(stamps_ns))
    return layout.messages()


def pose_stampeds(stamps_ns: np.ndarray, xyz_m: np.ndarray, wxyz: np.ndarray | None = None) -> np.ndarray:
    """geometry_msgs/PoseStamped of every tick (stamps in ns, positions (ticks, 3), unit
    quaternions (ticks, 4) as (w, x, y, z), the identity when None), frame ''."""
    layout = Layout()
    layout.header(stamps_ns, '')
    layout.doubles(xyz_m)
    orientation = (np.tile([0.0, 0.0, 0.0, 1.0], (len(stamps_ns), 1)) if wxyz is None
                   else np.asarray(wxyz, dtype=float)[:, [1, 2, 3, 0]])   # ROS orders it x, y, z, w
    layout.doubles(orientation)
    return layout.messages()
