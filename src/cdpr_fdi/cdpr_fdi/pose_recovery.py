"""A platform's recovery after a cable failure, in pose space (issue 29; docs/platform.md).

Where the remaining cables can hold the platform at rest where it is at the naming —
static tensions within [τ_min, τ_max] exist at its pose — position control takes over at
once (RECOVERY_MOVE): a quintic from the platform's velocity brings its position to rest,
its orientation held; then a straight quintic takes the position to the safe pose's while
the orientation turns about a fixed axis to the safe pose's with the same law; then
SAFE_HOLD. The move is tabulated per tick for the remaining cables, their tensions
planned `plan_tension_margin_n` above τ_min; a plan whose tensions leave the bounds is
planned again, braking sooner and moving slower, `replan_attempts` times. Where none
fits — the move passes poses where the cables cannot pull its wrench with the margin —
the slowest plan is tabulated with the floored least-squares tensions on those rows
(cdpr_control.tension_distribution.FlooredLeastSquares): the wrench out of reach is
missed by a little, every cable planned at least at the floor, and the joints' position
control keeps the platform on its way.

Where no static tensions within the bounds hold the platform at its pose, a cable goes
slack whatever the drives do: RecoveryInfeasible, so the supervisor holds the drums
(FAULT) and says why. Neither of the two ways tried from there is kept
(docs/platform.md): the point mass's phase 1, tensions carried in tension space with the
joints let go, does not hold a platform's orientation (the crossed platform turned 90°
within 0.23 s of the naming); position control with the floored tensions brought two
runs in three to the safe pose with a cable slack for seconds, and turned the platform
over in the third while its motors, whose paid-out lengths matched the safe pose, could
not tell.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.pose_reference import tabulate_pose_reference
from cdpr_control.pose_trajectories import PoseTrajectory, Turn
from cdpr_control.robot import Robot
from cdpr_control.rotation import difference
from cdpr_control.safe_pose import tension_margin_n
from cdpr_control.tension_distribution import (FlooredLeastSquares, InfeasibleTensionError, TensionDistribution,
                                               make_tension_distribution)
from cdpr_control.trajectories import HermiteQuintic, Hold, Sequence
from cdpr_msgs_py.contract import RECOVERY_MOVE, SAFE_HOLD

from .config import RecoveryConfig
from .recovery import RecoveryInfeasible, TabulatedMove, safe_pose_for

# The axis of a turn by no angle: any will do.
NO_TURN_AXIS = (0.0, 0.0, 1.0)


def check_held(robot: Robot, attached: np.ndarray, position_m, orientation) -> None:
    """RecoveryInfeasible unless static tensions of the `attached` cables within the
    bounds hold the platform at rest at the pose (p, q)."""
    if tension_margin_n(robot, position_m, orientation, attached) < 0.0:
        raise RecoveryInfeasible(
            f'no tensions of the {np.count_nonzero(attached)} cables left within [{robot.tension_min_n:g}, '
            f'{robot.tension_max_n:g}] N hold the platform where it is (p = '
            f'({", ".join(f"{value:.3f}" for value in position_m)}) m): a cable goes slack whatever the drives '
            f'do, and no recovery from there is built for a platform (docs/platform.md)')


class PoseRecovery(TabulatedMove):
    """Steps through a platform's recovery, one control tick at a time, as Recovery does
    a point mass's: `setpoint(tick, angle, speed)` gives the mode and the joint reference
    of the next tick."""

    def __init__(self, robot: Robot, config: RecoveryConfig, distribution: TensionDistribution,
                 period_s: float, attached: np.ndarray, start_tick: int, position_m, orientation,
                 velocity_m_s):
        """From the pose (p, q) and velocity (m/s) the remaining (`attached`) cables give at
        detection, to their safe pose (recovery.safe_pose_for); RecoveryInfeasible where no
        static tensions within the bounds hold the platform at that pose (checked first: a
        safe pose the supervisor's start did not find, after several cables, takes ~0.2 s),
        or where there is no safe pose."""
        check_held(robot, attached, position_m, orientation)
        safe = safe_pose_for(robot, config, attached)
        self.robot = robot
        self.config = config
        self.period_s = period_s
        self.attached = np.asarray(attached, dtype=bool).copy()
        self.safe_point_m = safe.position_m
        self.safe_orientation = safe.orientation
        self.distribution = make_tension_distribution(
            distribution.name, distribution.tension_min_n + config.plan_tension_margin_n, distribution.tension_max_n)
        self.mode = RECOVERY_MOVE
        self.start_tick = start_tick
        self.phase_ticks = {RECOVERY_MOVE: start_tick}
        self.timed_out = False
        self.outside_bounds: str | None = None
        self.table = self.plan(np.asarray(position_m, dtype=float), orientation,
                               np.asarray(velocity_m_s, dtype=float))

    def plan(self, position_m, orientation, velocity_m_s):
        """The move's joint references per tick, slower at each try whose tensions leave
        the bounds; the slowest with the floored least-squares tensions where none fits
        (module docstring), saying why in `outside_bounds` (None where a plan fits)."""
        config = self.config
        brake_s = config.brake_s(float(np.linalg.norm(velocity_m_s)))
        for attempt in range(config.replan_attempts + 1):
            slowdown = config.replan_slowdown ** attempt
            move = self.move(position_m, orientation, velocity_m_s, brake_s / slowdown, slowdown)
            try:
                table = tabulate_pose_reference(self.robot, self.distribution, move, self.period_s, self.attached)
            except InfeasibleTensionError as err:
                self.outside_bounds = str(err)
                continue
            self.outside_bounds = None
            return table
        return tabulate_pose_reference(self.robot, FlooredLeastSquares(self.distribution), move, self.period_s,
                                       self.attached)

    def move(self, position_m, orientation, velocity_m_s, brake_s: float, slowdown: float) -> PoseTrajectory:
        """Brake over `brake_s` (to half its speed times that time ahead), then a quintic to
        the safe pose, `slowdown` times longer than configured, then rest there."""
        rest = position_m + 0.5 * brake_s * velocity_m_s
        turn = difference(self.safe_orientation, orientation)
        angle = float(np.linalg.norm(turn))
        move_s = self.config.move_s(float(np.linalg.norm(self.safe_point_m - rest))) * slowdown
        path = Sequence([HermiteQuintic(position_m, velocity_m_s, rest, np.zeros(3), brake_s),
                         HermiteQuintic(rest, np.zeros(3), self.safe_point_m, np.zeros(3), move_s),
                         Hold(self.safe_point_m, self.period_s)])
        return PoseTrajectory(path, Turn(orientation, turn / angle if angle > 0.0 else NO_TURN_AXIS, angle,
                                         move_s, brake_s))

    def tabulated(self) -> tuple[int, object]:
        return self.start_tick, self.table

    def setpoint(self, tick: int, angle_rad, angular_velocity_rad_s):
        """(mode, None, JointReference or None) for tick + 1: the move's rows, its last one
        on the tick SAFE_HOLD starts, then nothing (the controller holds it at rest)."""
        if self.mode == SAFE_HOLD:
            return self.mode, None, None
        reference = self.move_setpoint(tick)
        return self.mode, None, reference
