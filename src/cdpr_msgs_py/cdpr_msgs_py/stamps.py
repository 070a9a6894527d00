"""Time as the graph counts it: whole nanoseconds, and the (sec, nanosec) pairs of ROS
stamps. One definition for the nodes (rclpy's messages) and the bags (rosbags' types),
which is why nothing here imports a message package."""
from __future__ import annotations

NANOSECONDS = 1_000_000_000


def seconds_to_ns(seconds: float) -> int:
    """A period or a wait (s) in whole nanoseconds."""
    return int(round(seconds * NANOSECONDS))


def stamp_to_ns(stamp) -> int:
    """Nanoseconds of any stamp with `sec` and `nanosec` (builtin_interfaces/Time)."""
    return stamp.sec * NANOSECONDS + stamp.nanosec


def ns_parts(stamp_ns: int) -> tuple[int, int]:
    """(sec, nanosec) of a stamp in nanoseconds."""
    return divmod(stamp_ns, NANOSECONDS)
