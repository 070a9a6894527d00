"""A platform's recovery after a cable failure, in pose space (issue 29; docs/platform.md).

Where the remaining cables can hold the platform at rest where it is at the naming —
static tensions within [τ_min, τ_max] exist at its pose — position control takes over at
once (RECOVERY_MOVE): quintics from the platform's twist bring its position and its
orientation to rest (BrakedTurn: a plan that took the orientation as still would step
the motors' speeds, and the platform turns fast in the ticks after a break); then a
straight quintic takes the position to the safe pose's while the orientation turns about
a fixed axis to the safe pose's with the same law; then SAFE_HOLD. The move is tabulated
per tick for the remaining cables, their tensions planned `plan_tension_margin_n` above
τ_min, and tried braking sooner and moving slower, then braking as first planned and
moving slower: the first try that keeps the margin is taken. Named near the border,
where the cables cannot keep that margin even at rest, each try is planned with the
margin lowered where a pose needs it (cdpr_control.tension_distribution.LoweredFloor:
the wrench pulled exactly, the least tension as high as the pose allows, not below
τ_min) and the try with the highest least tension is taken. Where no try keeps every
cable at τ_min, the slowest is tabulated with the floored least-squares tensions on those
rows (FlooredLeastSquares): the wrench out of reach is missed by a little, and the joints'
position control keeps the platform on its way. The brake starts lifting the platform
(`brake_lift_m_s2`: every cable then pulls more than at rest, a margin for the ticks
in which the drives take over), and the move's first tick goes `command_step_share` of
the way from the torques commanded at the naming (ease_in).

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
from cdpr_control.pose_trajectories import BrakedTurn, PoseTrajectory
from cdpr_control.robot import Robot
from cdpr_control.safe_pose import tension_margin_n
from cdpr_control.tension_distribution import (FlooredLeastSquares, InfeasibleTensionError, LoweredFloor,
                                               TensionDistribution, make_tension_distribution)
from cdpr_control.trajectories import HermiteQuintic, Hold, Sequence
from cdpr_msgs_py.contract import RECOVERY_MOVE, SAFE_HOLD

from .config import RecoveryConfig
from .recovery import RecoveryInfeasible, TabulatedMove, safe_pose_for

# Least tensions (N) of two tries this close count as equal: the faster is kept.
LEAST_TENSION_RESOLUTION_N = 0.01


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
                 velocity_m_s, angular_velocity_rad_s, command_nm):
        """From the pose (p, q) and twist (v m/s, ω rad/s) the remaining (`attached`) cables
        give at detection, and the torques (N·m) the motors were commanded on that tick, to
        their safe pose (recovery.safe_pose_for); RecoveryInfeasible where no static
        tensions within the bounds hold the platform at that pose (checked first: a safe
        pose the supervisor's start did not find, after several cables, takes ~0.2 s), or
        where there is no safe pose."""
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
                               np.asarray(velocity_m_s, dtype=float), np.asarray(angular_velocity_rad_s, dtype=float))
        self.ease_in(np.asarray(command_nm, dtype=float))

    def plan(self, position_m, orientation, velocity_m_s, angular_velocity_rad_s):
        """The move's joint references per tick (module docstring): the first of the tries
        whose tensions keep the planned margin; else, of the tries, the one whose least
        tension is highest with the margin lowered where a pose needs it; else the slowest
        with the floored least-squares tensions. `outside_bounds` says why where no try
        kept the margin (None where one did)."""
        config = self.config
        brake_s = config.brake_s(float(np.linalg.norm(velocity_m_s)))
        # braking sooner keeps a platform near the border inside it, braking gently asks
        # less of the cables: each with the move slower and slower
        slowdowns = [config.replan_slowdown ** attempt for attempt in range(config.replan_attempts + 1)]
        tries = ([(brake_s / slowdown, slowdown) for slowdown in slowdowns]
                 + [(brake_s, slowdown) for slowdown in slowdowns[1:]])
        moves = [self.move(position_m, orientation, velocity_m_s, angular_velocity_rad_s, *each) for each in tries]
        for move in moves:
            try:
                table = tabulate_pose_reference(self.robot, self.distribution, move, self.period_s, self.attached)
            except InfeasibleTensionError as err:
                reason = str(err)
                continue
            return table
        lowered = LoweredFloor(self.distribution, self.robot.tension_min_n)
        best, best_least = None, -np.inf
        for move in moves:
            try:
                table = tabulate_pose_reference(self.robot, lowered, move, self.period_s, self.attached)
            except InfeasibleTensionError:
                continue
            least = float(np.min(table.tension_n[:, self.attached]))
            # a faster move unless a slower one keeps clearly more
            if least > best_least + LEAST_TENSION_RESOLUTION_N:
                best, best_least = table, least
        if best is not None:
            self.outside_bounds = (f'{reason}; planned with the margin each pose allows, the least tension '
                                   f'{best_least:.2f} N')
            return best
        self.outside_bounds = (f'{reason}; no try keeps every cable at {self.robot.tension_min_n:g} N: the slowest '
                               f'planned nearest the bounds')
        return tabulate_pose_reference(self.robot, FlooredLeastSquares(lowered), moves[len(slowdowns) - 1],
                                       self.period_s, self.attached)

    def ease_in(self, command_nm: np.ndarray) -> None:
        """The first row the controller tracks (row 1: row 0 is the naming tick's, already
        commanded) takes `command_step_share` of the step from `command_nm` to its
        feed-forward, the next row the rest: a step in torque rings elastic cables, and
        half of it rings them half as much (docs/platform.md)."""
        if len(self.table) < 2:
            return
        held = (1.0 - self.config.command_step_share) * (command_nm - self.table.feedforward_nm[1]) * self.attached
        self.table.feedforward_nm[1] += held
        self.table.tension_n[1] -= held / self.robot.motor.drum_radius_m

    def move(self, position_m, orientation, velocity_m_s, angular_velocity_rad_s, brake_s: float,
             slowdown: float) -> PoseTrajectory:
        """Brake position and orientation over `brake_s` (each on by half its speed times
        that time; the path starting with `brake_lift_m_s2` upward, which every cable pulls
        for), then a quintic to the safe pose, `slowdown` times longer than configured,
        then rest there."""
        rest = position_m + 0.5 * brake_s * velocity_m_s
        move_s = self.config.move_s(float(np.linalg.norm(self.safe_point_m - rest))) * slowdown
        gravity = np.linalg.norm(self.robot.gravity_m_s2)
        up = -self.robot.gravity_m_s2 / gravity if gravity > 0.0 else np.zeros(3)
        path = Sequence([HermiteQuintic(position_m, velocity_m_s, rest, np.zeros(3), brake_s,
                                        self.config.brake_lift_m_s2 * up),
                         HermiteQuintic(rest, np.zeros(3), self.safe_point_m, np.zeros(3), move_s),
                         Hold(self.safe_point_m, self.period_s)])
        return PoseTrajectory(path, BrakedTurn(orientation, angular_velocity_rad_s, brake_s, self.safe_orientation,
                                               move_s))

    def tabulated(self) -> tuple[int, object]:
        return self.start_tick, self.table

    def setpoint(self, tick: int, angle_rad, angular_velocity_rad_s):
        """(mode, None, JointReference or None) for tick + 1: the move's rows, its last one
        on the tick SAFE_HOLD starts, then nothing (the controller holds it at rest)."""
        if self.mode == SAFE_HOLD:
            return self.mode, None, None
        reference = self.move_setpoint(tick)
        return self.mode, None, reference
