"""The paper's named motions (Tables 4 and 6, the circle) read from a scenario YAML."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cdpr_control.config import Section, load_config, load_section
from cdpr_control.geometry.pose_trajectories import NO_TURN, NoTurn, PoseTrajectory, Turn
from cdpr_control.geometry.trajectories import Circle, Hold, Sequence, StraightLine, quintic_time_at_fraction

MOTION_TYPES = ('line', 'circle')


@dataclass
class Motion:
    """A rest → move → rest reference: the move is the middle segment of `trajectory`, the
    position's path; `turn` the orientation's over it (a platform's; NO_TURN for a point
    mass, whose pose has none)."""

    name: str
    trajectory: Sequence
    turn: Turn | NoTurn = NO_TURN

    @property
    def pose_trajectory(self) -> PoseTrajectory:
        """The motion of the pose, as it is tabulated."""
        return PoseTrajectory(self.trajectory, self.turn)

    @property
    def start_orientation(self) -> np.ndarray | None:
        """The orientation it starts from; None for a pose without one."""
        orientation = self.turn.sample(0.0)[0]
        return orientation if orientation.size else None

    @property
    def move(self):
        return self.trajectory.segments[1]

    @property
    def move_start_s(self) -> float:
        return self.trajectory.segment_start_s(1)

    @property
    def move_end_s(self) -> float:
        return self.trajectory.segment_start_s(2)

    def time_at_fraction(self, fraction: float) -> float:
        """Time (s) when the move has covered `fraction` of its path (0.5: the midpoint)."""
        return self.move_start_s + quintic_time_at_fraction(fraction, self.move.duration_s)

    def failure_time(self, at_s: float | None = None, at_fraction: float | None = None) -> float:
        """When a scheduled failure happens: at `at_s`, else at `at_fraction` of the move
        (the midpoint when neither is given, as in the paper's Tables 4 and 6)."""
        if at_s is not None:
            return float(at_s)
        return self.time_at_fraction(0.5 if at_fraction is None else at_fraction)


def motion_from_section(name: str, motion: Section, defaults: Section, reverse: bool = False) -> Motion:
    """Build the named motion; `reverse` runs its path from the end back to the start."""
    speed = (motion if motion.has('peak_speed_m_s') else defaults).number('peak_speed_m_s', positive=True)
    kind = motion.string('type', choices=MOTION_TYPES)
    if kind == 'line':
        move = StraightLine.with_peak_speed(motion.vector('start', 3), motion.vector('goal', 3), speed)
    else:
        move = Circle.with_peak_speed(
            motion.vector('centre', 3), motion.number('radius_m', positive=True),
            np.radians(motion.number('start_angle_deg')), np.radians(motion.number('sweep_deg')),
            speed)
    if reverse:
        move = move.reversed()
    before = defaults.number('rest_before_s', non_negative=True)
    after = defaults.number('rest_after_s', non_negative=True)
    trajectory = Sequence([Hold(move.start, before), move, Hold(move.end, after)])
    return Motion(name + (' (reversed)' if reverse else ''), trajectory)


def motion_names(path: str | Path) -> list[str]:
    return list(load_section(path, 'motions').data)


def settled_motion(path: str | Path, name: str, reverse: bool = False) -> Section:
    """The motion `name` of the YAML file at `path` as a settled run carries it: its entry
    with `motion_defaults` filled in, its name, its direction, and the peak speed of a
    move to a goal (m/s)."""
    document = load_config(path)
    motions = document.section('motions')
    if not motions.has(name):
        raise motions.error(name, f'is not a known motion; choose one of {", ".join(motions.data)}')
    defaults = document.section('motion_defaults')
    entry = motions.section(name)
    if not isinstance(entry.data, dict):
        raise motions.error(name, 'must be a mapping')
    settled = {**defaults.data, **entry.data, 'name': name, 'reverse': bool(reverse),
               'goal_peak_speed_m_s': defaults.number('peak_speed_m_s', positive=True)}
    return Section(settled, path, entry.prefix)


def motion_from_settled(motion: Section) -> Motion:
    """The Motion a settled motion section describes."""
    return motion_from_section(motion.string('name'), motion, motion, motion.raw('reverse', False))


def load_motion(path: str | Path, name: str, reverse: bool = False) -> Motion:
    """The motion `name` of the `motions` section of the YAML file at `path`."""
    return motion_from_settled(settled_motion(path, name, reverse))
