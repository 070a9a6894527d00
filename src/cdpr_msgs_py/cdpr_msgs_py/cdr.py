"""The CDR bytes of the loop's messages: a run's per-tick messages all ticks of a topic
at once (a bag's), and one JointState of the loop at a time (a node's).

A JointState of a given robot, or a PoseStamped, has the same layout on every tick:
only the stamp and the numbers change. So the bytes of one message are laid out once
(little-endian CDR as ROS 2 serialises it, alignment counted from after the 4-byte
encapsulation header) and the values are written into them, instead of building and
serialising a message object: for a bag, every tick's into a (ticks, bytes) array with
numpy; for a node, each message as it is published (JointStateCodec), and read back at
the same offsets when it comes in laid out so. A node's delivery was ~200 µs of CPU here,
the message objects a fifth of it (docs/performance.md). `tests/test_bulk_cdr.py` checks
the bytes against rosbags' serialiser and the codec against rclpy's.
"""
from __future__ import annotations

import struct
from math import isfinite

import numpy as np

from .stamps import NANOSECONDS, ns_parts

ENCAPSULATION = b'\x00\x01\x00\x00'   # CDR, little endian
# CDR encapsulation identifiers (the first 2 bytes of a serialized message), by byte order.
CDR_BYTE_ORDER = {b'\x00\x00': '>', b'\x00\x01': '<'}


def cdr_stamp_ns(data: bytes) -> int:
    """The stamp (ns) a serialized message starts with (builtin_interfaces/Time first: a
    std_msgs/Header, or the Clock's Time); ValueError for bytes that are not plain CDR."""
    order = CDR_BYTE_ORDER.get(bytes(data[:2]))
    if order is None:
        raise ValueError(f'not a plain CDR message (encapsulation {bytes(data[:2]).hex()})')
    sec, nanosec = struct.unpack_from(f'{order}iI', data, len(ENCAPSULATION))
    return sec * NANOSECONDS + nanosec


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


class JointStateLayout:
    """Where the stamp and the values of one JointState of these joint names and these
    field sizes go in its bytes, frame ''."""

    def __init__(self, names: list[str], sizes: tuple[int, int, int]):
        layout = Layout()
        layout.header(np.zeros(1, dtype=np.int64), '')
        layout.uint32(len(names))
        for name in names:
            layout.string(name)
        for size in sizes:
            layout.double_sequence(np.zeros((1, size)), 1)
        self.template = bytes(layout.messages()[0])
        start = len(ENCAPSULATION)
        self.stamp_offset = start + layout.slots[0][0]
        self.value_offsets = [start + offset for offset, _ in layout.slots[2:]]


class JointStateCodec:
    """One JointState of the joints `names` as CDR bytes (`encode`), and such bytes as
    (stamp ns, position, velocity, effort) (`decode`: None for bytes laid out otherwise,
    which rclpy's deserialiser then reads)."""

    def __init__(self, names: list[str]):
        self.names = list(names)
        self.encoded_names = [name.encode() + b'\x00' for name in self.names]
        self.layouts: dict[tuple[int, int, int], JointStateLayout] = {}
        # the bytes from the frame's length to the last name as `encode` lays them out
        # (padding zero): a message laid out so is read at fixed offsets
        own = JointStateLayout(self.names, (0, 0, 0)).template
        self.names_end = len(own) - 12
        self.own_names = own[12:self.names_end]

    def encode(self, stamp_ns: int, position=(), velocity=(), effort=()) -> bytes:
        arrays = [np.asarray(values, dtype='<f8').ravel() for values in (position, velocity, effort)]
        sizes = tuple(array.size for array in arrays)
        layout = self.layouts.get(sizes)
        if layout is None:
            layout = self.layouts[sizes] = JointStateLayout(self.names, sizes)
        data = bytearray(layout.template)
        sec, nanosec = ns_parts(int(stamp_ns))
        # int32 seconds, wrapped past 2038 as rclpy's serialiser wraps them
        struct.pack_into('<iI', data, layout.stamp_offset, (sec + 2 ** 31) % 2 ** 32 - 2 ** 31, nanosec)
        for offset, array in zip(layout.value_offsets, (array for array in arrays if array.size)):
            data[offset:offset + 8 * array.size] = array.tobytes()
        return bytes(data)

    def decode(self, data: bytes):
        """(stamp ns, position, velocity, effort: tuples of floats) of a little-endian
        JointState of these names; None where it is laid out otherwise (other names,
        another encoding, cut short). Values are not checked here."""
        try:
            if data[:4] != ENCAPSULATION:
                return None
            sec, nanosec = _STAMP.unpack_from(data, 4)
            if data[12:self.names_end] == self.own_names:
                offset = self.names_end
            else:
                offset = self.names_offset(data)
                if offset is None:
                    return None
            fields = []
            for _ in range(3):
                offset = _aligned(offset, 4)
                count = _COUNT.unpack_from(data, offset)[0]
                offset += 4
                if count:
                    offset = _aligned(offset, 8)
                    fields.append(_doubles(count).unpack_from(data, offset))
                    offset += 8 * count
                else:
                    fields.append(())
        except struct.error:
            return None
        return (sec * NANOSECONDS + nanosec, *fields)

    def names_offset(self, data: bytes) -> int | None:
        """Where the values start in bytes whose frame and names another writer laid out
        (its padding holds whatever its buffer held: not compared); None: other names."""
        frame = _COUNT.unpack_from(data, 12)[0]
        offset = _aligned(16 + frame, 4)
        if _COUNT.unpack_from(data, offset)[0] != len(self.names):
            return None
        offset += 4
        for name in self.encoded_names:
            offset = _aligned(offset, 4)
            length = _COUNT.unpack_from(data, offset)[0]
            if length != len(name) or data[offset + 4:offset + 4 + length] != name:
                return None
            offset += 4 + length
        return offset


_STAMP, _COUNT = struct.Struct('<iI'), struct.Struct('<I')
_DOUBLES: dict[int, struct.Struct] = {}


def _doubles(count: int) -> struct.Struct:
    found = _DOUBLES.get(count)
    if found is None:
        found = _DOUBLES[count] = struct.Struct(f'<{count}d')
    return found


def _aligned(offset: int, size: int) -> int:
    """`offset` (counted from the start of the bytes, the 4-byte encapsulation first)
    aligned as CDR aligns it, from after the encapsulation."""
    body = offset - len(ENCAPSULATION)
    return offset + (-body % size)


def all_finite(values) -> bool:
    """Every value finite (math.isfinite per value: np.isfinite and np.all cost ~3 µs on m values)."""
    return all(map(isfinite, values))
