"""Reference motions of an end-effector's pose: a path of its position (trajectories.py)
and a turn of its orientation, both starting and ending at rest. A point mass's pose has
no orientation: its turn, NO_TURN, has figures of no entries (a pose of 3 numbers,
a twist of 3), so that one code path serves either body.

A turn rotates the platform by `angle_rad` about a fixed world axis, from its starting
orientation, with the quintic rest-to-rest law; with the axis fixed, ω = axis · angle · ṡ
and α = axis · angle · s̈ exactly. A turn of angle 0 keeps the orientation constant.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.geometry.rotation import difference, from_rotation_vector, normalised, product
from cdpr_control.geometry.trajectories import HermiteQuintic, Trajectory, quintic_profile

# The axis of a turn by no angle: any will do.
NO_TURN_AXIS = (0.0, 0.0, 1.0)


@dataclass(frozen=True)
class PoseSample:
    """Position p (m), orientation q, velocity v (m/s), angular velocity ω (rad/s),
    acceleration a (m/s²), angular acceleration α (rad/s²); world frame."""

    position_m: np.ndarray
    orientation: np.ndarray
    velocity_m_s: np.ndarray
    angular_velocity_rad_s: np.ndarray
    acceleration_m_s2: np.ndarray
    angular_acceleration_rad_s2: np.ndarray

    @property
    def pose(self) -> np.ndarray:
        """(p, q): 3 numbers, 7 with an orientation; a row of each of a stack."""
        return np.concatenate([self.position_m, self.orientation], axis=-1)

    @property
    def twist(self) -> np.ndarray:
        """(v, ω)."""
        return np.concatenate([self.velocity_m_s, self.angular_velocity_rad_s], axis=-1)

    @property
    def twist_rate(self) -> np.ndarray:
        """(a, α)."""
        return np.concatenate([self.acceleration_m_s2, self.angular_acceleration_rad_s2], axis=-1)

    @property
    def motion(self) -> tuple:
        """(pose, twist, its rate), the arguments of the inverse dynamics."""
        return self.pose, self.twist, self.twist_rate


class NoTurn:
    """The orientation's part of a point mass's motion: none (figures of no entries)."""

    @staticmethod
    def sample(t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        nothing = np.empty(np.shape(t) + (0,))
        return nothing, nothing, nothing

    def reversed(self, total_s: float) -> 'NoTurn':
        return self


NO_TURN = NoTurn()


class Turn:
    """The orientation's part of a motion: from `start` by `angle_rad` about `axis`
    (world frame), over `duration_s` beginning `delay_s` after the motion's start."""

    def __init__(self, start, axis, angle_rad: float, duration_s: float, delay_s: float = 0.0):
        axis = np.asarray(axis, dtype=float)
        if np.linalg.norm(axis) == 0.0 or duration_s <= 0.0:
            raise ValueError('a turn needs a non-zero axis and a positive duration')
        self.start = normalised(start)
        self.axis = axis / np.linalg.norm(axis)
        self.angle_rad = float(angle_rad)
        self.duration_s = float(duration_s)
        self.delay_s = float(delay_s)

    @classmethod
    def between(cls, start, goal, duration_s: float, delay_s: float = 0.0) -> 'Turn':
        """The turn from `start` to `goal` about the fixed axis of their difference."""
        start = normalised(start)
        turn = difference(goal, start)
        angle = float(np.linalg.norm(turn))
        return cls(start, turn / angle if angle > 0.0 else NO_TURN_AXIS, angle, duration_s, delay_s)

    def sample(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, ω, α) at time t (s) of the motion; of each time of an array t (n × 4, n × 3)."""
        turned, angular_velocity, angular_acceleration = (
            np.multiply.outer(self.angle_rad * np.asarray(value), self.axis)
            for value in quintic_profile(t - self.delay_s, self.duration_s))
        return normalised(product(from_rotation_vector(turned), self.start)), angular_velocity, angular_acceleration

    def reversed(self, total_s: float) -> 'Turn':
        """The turn run backward within a motion of `total_s`."""
        end = self.sample(self.delay_s + self.duration_s)[0]
        return Turn(end, self.axis, -self.angle_rad, self.duration_s, total_s - self.delay_s - self.duration_s)


class BrakedTurn:
    """A recovery's orientation braked: from `start` turning at ω_0 (rad/s, world frame),
    brought to rest about ω_0's axis over `brake_s` by the Hermite quintic, turned on by
    ω_0 brake_s / 2 (as a path braked by HermiteQuintic goes on by half its speed times
    that time), then at rest. A brake already under way is taken over with its angular
    acceleration α_0 and turned on by `turned_rad` (φ, rad) instead, along ω_0's axis as
    such a brake's are. The rotation vector φ(t) keeps ω_0's direction, so ω = φ̇ and
    α = φ̈ exactly.
    """

    def __init__(self, start, angular_velocity_rad_s, brake_s: float, angular_acceleration_rad_s2=(0.0, 0.0, 0.0),
                 turned_rad=None):
        spin = np.asarray(angular_velocity_rad_s, dtype=float)
        self.start = normalised(start)
        turned = 0.5 * brake_s * spin if turned_rad is None else np.asarray(turned_rad, dtype=float)
        self.brake = HermiteQuintic(np.zeros(3), spin, turned, np.zeros(3), brake_s, angular_acceleration_rad_s2)

    def sample(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, ω, α) at time t (s) of the motion; of each time of an array t (n × 4, n × 3)."""
        braked, angular_velocity, angular_acceleration = self.brake.sample(t)
        return normalised(product(from_rotation_vector(braked), self.start)), angular_velocity, angular_acceleration


class PoseTrajectory:
    """An end-effector's motion: `path` for its position, `turn` (a Turn or BrakedTurn; a
    point mass's NO_TURN) for its orientation."""

    def __init__(self, path: Trajectory, turn: Turn | BrakedTurn | NoTurn = NO_TURN):
        self.path = path
        self.turn = turn
        self.duration_s = path.duration_s

    def sample(self, t: float) -> PoseSample:
        position, velocity, acceleration = self.path.sample(t)
        orientation, angular_velocity, angular_acceleration = self.turn.sample(t)
        return PoseSample(position, orientation, velocity, angular_velocity, acceleration, angular_acceleration)

    def reversed(self) -> 'PoseTrajectory':
        return PoseTrajectory(self.path.reversed(), self.turn.reversed(self.duration_s))
