"""A platform's reference motion: the path of its position (geometry.motions) and the turn
of its orientation over the move."""
from __future__ import annotations

import dataclasses

import numpy as np

from cdpr_control.config import Section
from cdpr_control.geometry.motions import Motion, motion_from_settled
from cdpr_control.geometry.pose_trajectories import Turn
from cdpr_control.geometry.rotation import from_axis_angle, product


def pose_motion_from_settled(motion: Section, start_orientation) -> Motion:
    """A platform's motion from a settled motion section: its path as `motion_from_settled`
    reads it, and its turn (`with_turn`)."""
    return with_turn(motion_from_settled(motion), motion, start_orientation)


def with_turn(path: Motion, motion: Section, start_orientation) -> Motion:
    """The motion `path` (read from the settled `motion` section) with the section's
    `turn` (axis: a world direction, angle_deg) over the move, from `start_orientation`;
    without `turn` the orientation stays `start_orientation`."""
    turn = motion.section('turn', {})
    axis = turn.vector('axis', 3, [0.0, 0.0, 1.0])
    if not np.linalg.norm(axis) > 0.0:
        raise turn.error('axis', 'must be a non-zero direction')
    angle = np.radians(turn.number('angle_deg', 0.0))
    if motion.raw('reverse', False):
        start_orientation = product(from_axis_angle(axis, angle), start_orientation)
        angle = -angle
    return dataclasses.replace(path, turn=Turn(start_orientation, axis, angle, path.move.duration_s,
                                               path.move_start_s))
