"""A platform's reference motion: the path of its position (geometry.motions) and the turn
of its orientation over the move."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.config import Section
from cdpr_control.geometry.motions import Motion, motion_from_settled
from cdpr_control.geometry.pose_trajectories import PoseTrajectory, Turn
from cdpr_control.geometry.rotation import from_axis_angle, product


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
    (`path`, whose timing it shares) and the pose trajectory with the turn."""

    path: Motion
    trajectory: PoseTrajectory

    @property
    def pose_trajectory(self) -> PoseTrajectory:
        return self.trajectory

    @property
    def name(self) -> str:
        return self.path.name

    @property
    def start_orientation(self) -> np.ndarray:
        return self.trajectory.sample(0.0).orientation
