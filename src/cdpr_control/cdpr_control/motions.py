"""The paper's named motions (Tables 4 and 6, the circle) read from a scenario YAML."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .config import Section, load_config, load_section
from .pose_reference import sampled
from .pose_trajectories import PoseTrajectory, Turn
from .reference import tick_times
from .rotation import from_axis_angle, product
from .trajectories import Circle, Hold, Sequence, StraightLine, quintic_time_at_fraction

MOTION_TYPES = ('line', 'circle')


@dataclass
class Motion:
    """A rest → move → rest reference: the move is the middle segment of `trajectory`."""

    name: str
    trajectory: Sequence

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


def pose_motion_from_settled(motion: Section, start_orientation) -> 'PoseMotion':
    """A platform's motion from a settled motion section: its path as `motion_from_settled`
    reads it, and its turn (`with_turn`)."""
    return with_turn(motion_from_settled(motion), motion, start_orientation)


def with_turn(path: Motion, motion: Section, start_orientation) -> 'PoseMotion':
    """The platform's motion of `path` (read from the settled `motion` section) with the
    section's `turn` (axis: a world direction, angle_deg) over the move, from
    `start_orientation`; without `turn` the orientation stays `start_orientation`."""
    turn = motion.section('turn', {})
    axis = turn.vector('axis', 3, [0.0, 0.0, 1.0])
    if not np.linalg.norm(axis) > 0.0:
        raise turn.error('axis', 'must be a non-zero direction')
    angle = np.radians(turn.number('angle_deg', 0.0))
    if motion.raw('reverse', False):
        start_orientation = product(from_axis_angle(axis, angle), start_orientation)
        angle = -angle
    return PoseMotion(path, PoseTrajectory(path.trajectory, Turn(start_orientation, axis, angle,
                                                                  path.move.duration_s, path.move_start_s)))


@dataclass
class PoseMotion:
    """A platform's rest → move → rest reference: the point-mass motion of its position
    (`motion`, whose timing it shares) and the pose trajectory with the turn."""

    motion: Motion
    trajectory: PoseTrajectory

    @property
    def name(self) -> str:
        return self.motion.name


def reference_poses(robot, motion: Section, period_s: float) -> tuple[np.ndarray, np.ndarray | None]:
    """The poses (positions n × 3, a platform's orientations n × 4, else None) of the
    settled `motion` at every tick, as the trajectory generator tabulates them (its
    reference table's rows, to the bit): what the plant simulator tracks its truth against."""
    if robot.platform is None:
        path = motion_from_settled(motion).trajectory
        return path.sample(tick_times(period_s, path.duration_s))[0], None
    sample = sampled(pose_motion_from_settled(motion, robot.platform.home_orientation).trajectory, period_s)
    return sample.position_m, sample.orientation
