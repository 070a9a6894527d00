"""A platform steered to a pose by tensions kept within their bounds (docs/platform.md).

Where the cables left after a break cannot hold the platform at rest where it is, no
static tensions exist there, but some motion does: the platform is let move as tensions
within [τ_min + margin, τ_max] let it, towards the target pose. Each control period the
platform's rigid-body model is stepped under the tensions that come nearest (in a norm
that weighs moments `moment_weight` times a force's N, nearest_wrench) the wrench of a
critically damped pull towards the target,

    a_d = ω_p² (p* − p) − 2 ω_p v,   α_d = ω_q² φ(q*, q) − 2 ω_q ω,
    w_d = M s(t) (a_d, α_d) − (w_g − h),

the pull eased in by s(t), a smoothstep from 0 at the first row to 1 at `ease_in_s` (the
first tensions, nearest those that would hold the platform as it moves, step least from
what the drives pulled before: a step rings elastic cables below τ_min). The motion those
tensions give, M (a, α) = W τ + w_g − h, is the plan: a motion the
cables can pull without a slack or an overloaded cable, by construction (the drives then
track it, its wrench shared again by the recovery's distribution). The orientation is
pulled much harder than the position: a platform whose small rotational inertia is left
to the moments that the forces' best fit leaves turns over (docs/platform.md).

Rows are stepped as they are asked for (`extend`), so a realtime supervisor steps a tick's
worth at a time; they are the same however they are asked for.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .pose_dynamics import rigid_body
from .pose_kinematics import wrench_matrix
from .pose_trajectories import PoseSample
from .robot import Robot
from .rotation import difference, from_rotation_vector, normalised, product
from .tension_distribution.nearest_wrench import nearest_wrench


def stepped(position_m, orientation, velocity_m_s, angular_velocity_rad_s, acceleration,
            period_s: float) -> tuple:
    """(p, q, v, ω) one period on under the twist rate (a, α) (6), by semi-implicit Euler:
    the new twist moves the pose."""
    velocity = np.asarray(velocity_m_s, dtype=float) + period_s * acceleration[:3]
    angular_velocity = np.asarray(angular_velocity_rad_s, dtype=float) + period_s * acceleration[3:]
    return (np.asarray(position_m, dtype=float) + period_s * velocity,
            normalised(product(from_rotation_vector(period_s * angular_velocity), orientation)),
            velocity, angular_velocity)


@dataclass(frozen=True)
class ApproachGains:
    """The pull towards the target: natural frequencies (rad/s) of the position's and the
    orientation's critically damped pulls, how many N a moment's N·m counts as, and over
    how long (s) the pull is eased in from none."""

    position_frequency_rad_s: float
    orientation_frequency_rad_s: float
    moment_weight: float
    ease_in_s: float


class SteeredApproach:
    """The motion of a platform from `start` (a PoseSample; its accelerations unused) to the
    target pose under tensions of the `attached` cables within [tension_min_n,
    tension_max_n], stepped at `period_s` (module docstring). Row k is the state at
    k periods, with the acceleration the tensions give it there."""

    def __init__(self, robot: Robot, attached: np.ndarray, start: PoseSample, target_m, target_orientation,
                 gains: ApproachGains, tension_min_n: float, tension_max_n: float, period_s: float):
        self.robot = robot
        self.attached = np.asarray(attached, dtype=bool)
        self.target_m = np.asarray(target_m, dtype=float)
        self.target_orientation = normalised(target_orientation)
        self.gains = gains
        self.bounds_n = (tension_min_n, tension_max_n)
        self.period_s = period_s
        self.weights = np.array([1.0, 1.0, 1.0] + [gains.moment_weight] * 3)
        self.state = (np.asarray(start.position_m, dtype=float), normalised(start.orientation),
                      np.asarray(start.velocity_m_s, dtype=float),
                      np.asarray(start.angular_velocity_rad_s, dtype=float))
        self.rows: list[tuple] = []

    def extend(self, rows: int) -> None:
        """Step the platform until at least `rows` rows are planned."""
        while len(self.rows) < rows:
            position, orientation, velocity, angular_velocity = self.state
            acceleration = self.acceleration(position, orientation, velocity, angular_velocity)
            self.rows.append((position, orientation, velocity, angular_velocity, acceleration[:3], acceleration[3:]))
            self.state = stepped(position, orientation, velocity, angular_velocity, acceleration, self.period_s)

    def acceleration(self, position, orientation, velocity, angular_velocity) -> np.ndarray:
        """(a, α) the bounded tensions nearest the pull towards the target give the platform."""
        gains = self.gains
        # the pull eased in (smoothstep) from none at the first row
        share = 1.0 if gains.ease_in_s <= 0.0 else min(1.0, len(self.rows) * self.period_s / gains.ease_in_s)
        share = share * share * (3.0 - 2.0 * share)
        body = rigid_body(self.robot, orientation, angular_velocity)
        structure = wrench_matrix(self.robot, position, orientation)[0][:, self.attached]
        pull = share * np.concatenate([
            gains.position_frequency_rad_s ** 2 * (self.target_m - position)
            - 2.0 * gains.position_frequency_rad_s * velocity,
            gains.orientation_frequency_rad_s ** 2 * difference(self.target_orientation, orientation)
            - 2.0 * gains.orientation_frequency_rad_s * angular_velocity])
        tension = nearest_wrench(structure, body.mass_matrix @ pull - body.free_wrench, self.weights,
                                 *self.bounds_n)
        return np.linalg.solve(body.mass_matrix, structure @ tension + body.free_wrench)

    def samples(self, start: int, stop: int) -> PoseSample:
        """Rows [start, stop) as a PoseSample of stacks (stepped first where needed)."""
        self.extend(stop)
        return PoseSample(*(np.array(figure) for figure in zip(*self.rows[start:stop])))

    def error(self, row: int) -> tuple[float, float, float, float]:
        """At row `row`: the distance (m) and the angle (rad) to the target, the speed (m/s)
        and the angular speed (rad/s)."""
        self.extend(row + 1)
        position, orientation, velocity, angular_velocity, _, _ = self.rows[row]
        return (float(np.linalg.norm(self.target_m - position)),
                float(np.linalg.norm(difference(self.target_orientation, orientation))),
                float(np.linalg.norm(velocity)), float(np.linalg.norm(angular_velocity)))
