"""A platform steered to a pose by tensions kept within their bounds (docs/platform.md).

Where the cables left after a break cannot hold the platform at rest where it is, no
static tensions exist there, but some motion does: the platform is let move as tensions
within [τ_min + margin, τ_max] let it, towards the target pose. Each control period the
platform's rigid-body model is stepped under the tensions that come nearest (in a norm
that weighs moments `moment_weight` times a force's N, platform_substeps.nearest_wrench) the wrench of a
critically damped pull towards the target,

    a_d = ω_p² (p* − p) − 2 ω_p v,   α_d = ω_q² φ(q_c, q) − 2 ω_q ω,
    w_d = M s(t) (a_d, α_d) − (w_g − h),

the orientation pulled towards q_c = exp(c(s) φ(q*, q_0)) q_0, on the turn from the
start's q_0 to the target's q*, s = 1 − |p* − p| / |p* − p_0| (within [0, 1]) the share
of the start's distance covered: the orientations the cables left hold the platform at
shift with its position. c(s) is chosen before the first row (`aim_schedule`), at
`aim_samples` points of the straight way from p_0 to p*, as the share of the turn whose
holding tensions keep the largest margin there (as the safe pose's orientation is
chosen), 1 at p*: a platform turned to its safe orientation at once, far from its safe
point, was held there by no tensions (flung across the frame, turned 36°), and one kept
at its start's was held nowhere on its way by another break's cables. The least margin
of the poses so aimed at, where the cables hold the platform at all, bounds how far
above τ_min a re-steered try keeps its tensions (recovery_strategies.steered). The pull is
eased in by s(t), a smoothstep from 0 at the first row to 1 at `ease_in_s` (the
first tensions, nearest those that would hold the platform as it moves, step least from
what the drives pulled before: a step rings elastic cables below τ_min). The motion those
tensions give, M (a, α) = W τ + w_g − h, is the plan: a motion the
cables can pull without a slack or an overloaded cable, by construction (the drives then
track it, its wrench shared again by the recovery's distribution). The orientation is
pulled much harder than the position: a platform whose small rotational inertia is left
to the moments that the forces' best fit leaves turns over (docs/platform.md).

Rows are stepped as they are asked for (`extend`), so a realtime supervisor steps a tick's
worth at a time; they are the same however they are asked for. A row is stepped by the
compiled kernel platform_substeps.steered_rows (~10 µs where numpy took ~0.3 ms: a
realtime supervisor stepping it kept up with the loop only most of the time, docs/platform.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.platform import substeps as platform_substeps
from cdpr_control.platform.substeps import ROW_POSE, ROW_RATE, ROW_TWIST, ROW_WIDTH
from cdpr_control.geometry.pose_trajectories import PoseSample
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import difference, from_axis_angle, normalised, product
from cdpr_control.platform.safe_pose import tension_margins_n

# Rows are kept in an array grown this many rows at a time (10 s of a 2 ms period).
ROWS_PER_GROWTH = 5000


@dataclass(frozen=True)
class ApproachGains:
    """The pull towards the target: natural frequencies (rad/s) of the position's and the
    orientation's critically damped pulls, how many N a moment's N·m counts as, over
    how long (s) the pull is eased in from none, and at how many points of its way the
    orientation it turns through is chosen (aim_schedule)."""

    position_frequency_rad_s: float
    orientation_frequency_rad_s: float
    moment_weight: float
    ease_in_s: float
    aim_samples: int


@dataclass(frozen=True)
class AimSchedule:
    """The orientation's aim on a steered way (aim_schedule): the shares c of the turn at
    evenly spaced shares s of the way, and the least tension margin (N) of the poses they
    aim at, among those where the remaining cables hold the platform (the target's
    among them)."""

    shares: np.ndarray
    least_margin_n: float


def aim_schedule(robot: Robot, attached, start_pose, target_m, target_orientation, samples: int) -> AimSchedule:
    """c at `samples` shares s of the straight way from the pose `start_pose` (p_0, q_0) to
    the target (module docstring): the share of the turn from q_0 to the target's
    orientation whose holding tensions at p_0 + s (p* − p_0) keep the largest margin
    (safe_pose.tension_margins_n), among as many shares; 1 at the target; where no share
    holds the platform, interpolated from the points where one does. With it, the least
    of the margins the points where one does keep."""
    start_pose = np.asarray(start_pose, dtype=float)
    shares = np.linspace(0.0, 1.0, samples)
    positions = start_pose[:3] + shares[:, None] * (np.asarray(target_m, dtype=float) - start_pose[:3])
    turn = difference(target_orientation, start_pose[3:])
    angle = np.linalg.norm(turn)
    axis = turn / angle if angle > 0.0 else turn
    margins = np.column_stack([tension_margins_n(robot, positions, product(from_axis_angle(axis, share * angle),
                                                                            start_pose[3:]), attached)
                               for share in shares])
    aim = shares[np.argmax(margins, axis=1)]
    aimed_n = margins.max(axis=1)
    aim[-1], aimed_n[-1] = 1.0, margins[-1, -1]
    held = np.isfinite(aimed_n)
    held[-1] = True
    return AimSchedule(np.interp(shares, shares[held], aim[held]), float(aimed_n[held].min()))


class SteeredApproach:
    """The motion of a platform from `start` (a PoseSample; its accelerations unused) to the
    target pose under tensions of the `attached` cables within [tension_min_n,
    tension_max_n], stepped at `period_s` (module docstring). Row k is the state at
    k periods, with the acceleration the tensions give it there."""

    def __init__(self, robot: Robot, attached: np.ndarray, start: PoseSample, target_m, target_orientation,
                 gains: ApproachGains, tension_min_n: float, tension_max_n: float, period_s: float,
                 aim: AimSchedule | None = None):
        """`aim`: the schedule aim_schedule gives from `start`, where it has been made
        already (by the caller, for its margin, or for a look-ahead's copy); made here
        where None."""
        self.kernel = platform_substeps.kernel()
        self.constants = platform_substeps.constants_of(robot)
        self.exits, self.attachments, _ = platform_substeps.geometry_of(robot)
        self.attached = np.asarray(attached, dtype=float)
        self.target_m = np.asarray(target_m, dtype=float)
        self.target_orientation = normalised(target_orientation)
        self.target = np.concatenate([self.target_m, self.target_orientation])
        self.gains = np.array([gains.position_frequency_rad_s, gains.orientation_frequency_rad_s,
                               gains.moment_weight, gains.ease_in_s])
        self.bounds_n = np.array([tension_min_n, tension_max_n], dtype=float)
        self.period_s = period_s
        self.pose = np.concatenate([np.asarray(start.position_m, dtype=float), normalised(start.orientation)])
        self.origin = self.pose.copy()
        self.aim = (aim_schedule(robot, np.asarray(attached, dtype=bool), self.origin, self.target_m,
                                 self.target_orientation, gains.aim_samples) if aim is None else aim)
        self.twist = np.concatenate([np.asarray(start.velocity_m_s, dtype=float),
                                     np.asarray(start.angular_velocity_rad_s, dtype=float)])
        self.table = np.empty((0, ROW_WIDTH))
        self.count = 0

    def extend(self, rows: int) -> None:
        """Step the platform until at least `rows` rows are planned."""
        if rows <= self.count:
            return
        if rows > len(self.table):
            grown = np.empty((max(rows, len(self.table) + ROWS_PER_GROWTH), ROW_WIDTH))
            grown[:self.count] = self.table[:self.count]
            self.table = grown
        status = self.kernel.steered_rows(self.constants, self.exits, self.attachments, self.attached, self.origin,
                                          self.aim.shares, self.target, self.gains, self.bounds_n, self.period_s,
                                          self.count, self.pose, self.twist, self.table[self.count:rows])
        if status < 0:
            raise RuntimeError(f'steered approach: the nearest wrench failed ({status}) at row {self.count}')
        self.count = rows

    def samples(self, start: int, stop: int) -> PoseSample:
        """Rows [start, stop) as a PoseSample of stacks (stepped first where needed)."""
        self.extend(stop)
        rows = self.table[start:stop]
        return PoseSample(rows[:, ROW_POSE:ROW_POSE + 3].copy(), rows[:, ROW_POSE + 3:ROW_TWIST].copy(),
                          rows[:, ROW_TWIST:ROW_TWIST + 3].copy(), rows[:, ROW_TWIST + 3:ROW_RATE].copy(),
                          rows[:, ROW_RATE:ROW_RATE + 3].copy(), rows[:, ROW_RATE + 3:].copy())

    def errors(self, sample: PoseSample) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """At each row of `sample` (samples'): the distances (m) and the angles (rad) to the
        target, the speeds (m/s) and the angular speeds (rad/s)."""
        return (np.linalg.norm(self.target_m - sample.position_m, axis=1),
                np.linalg.norm(difference(self.target_orientation, sample.orientation), axis=1),
                np.linalg.norm(sample.velocity_m_s, axis=1), np.linalg.norm(sample.angular_velocity_rad_s, axis=1))
