"""End-effector recovery after a cable failure (paper §3.2, DESIGN §5).

Phase 1 (RECOVERY_TENSION): a quintic in tension space from t_R, the tensions that keep
the force the robot applied at detection (eq. 23–25), to t_SP, the static tensions at
the safe point (eq. 22). It needs no pose feedback, so it also works outside the
residual static-equilibrium workspace. Phase 2 (RECOVERY_MOVE), once every remaining
motor turns slower than the settle speed: forward kinematics of the remaining cables,
then a quintic move to SP (straight when the end-effector is at rest) under PD +
feed-forward with S_R. Then SAFE_HOLD.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.controller import JointReference, RECOVERY_MOVE, RECOVERY_TENSION, SAFE_HOLD
from cdpr_control.kinematics import cable_vectors, forward_kinematics
from cdpr_control.reference import tabulate_reference
from cdpr_control.robot import Robot
from cdpr_control.statics import static_tensions
from cdpr_control.tension_distribution import TensionDistribution
from cdpr_control.trajectories import (QUINTIC_PEAK_SPEED_RATIO, HermiteQuintic, Hold, Sequence,
                                       quintic_profile)
from cdpr_control.workspace import safe_point

from .config import RecoveryConfig


class RecoveryInfeasible(RuntimeError):
    """The remaining cables cannot hold the end-effector in 3 DOF."""


def safe_point_for(robot: Robot, config: RecoveryConfig, attached: np.ndarray) -> np.ndarray:
    """SP (m): the configured point of a single broken cable, else the barycentre of the
    residual SEW cross-section at the safe height."""
    broken = np.flatnonzero(~attached) + 1
    if broken.size == 1 and int(broken[0]) in config.safe_points_m:
        return config.safe_points_m[int(broken[0])].copy()
    try:
        return safe_point(robot, attached, config.safe_height_m)
    except ValueError as err:
        raise RecoveryInfeasible(f'no residual workspace at z = {config.safe_height_m} m: {err}') from None


def check_recoverable(robot: Robot, attached: np.ndarray) -> None:
    """RecoveryInfeasible unless at least 3 cables remain and they span 3 directions."""
    if np.count_nonzero(attached) < 3:
        raise RecoveryInfeasible(f'{np.count_nonzero(attached)} cables left: 3 DOF need 3')


def initial_tensions(robot: Robot, position_m: np.ndarray, attached: np.ndarray,
                     reference_position_m: np.ndarray, reference_tension_n: np.ndarray,
                     feedback_torque_nm: np.ndarray, floor_n: float) -> np.ndarray:
    """t_R = S_R⁺ f_f, f_f = m p̈ − w_e + f_FB (eq. 23–25), no tension below `floor_n`.

    m p̈ − w_e is the wrench the reference's tensions applied (S at the reference pose);
    f_FB = S_R t_FB with t_FB = −c_FB / ρ (our sign: pulling torques are negative). Where
    the remaining cables cannot apply f_f with tension to spare (the paper's hard case,
    outside the residual workspace), the cables that would drop below the floor are held
    at it and the others fit f_f in the least-squares sense: a small jump in force is
    better than a cable that goes slack and snaps taut again.
    """
    u_reference, _ = cable_vectors(robot.exit_points_m, reference_position_m)
    u_remaining, _ = cable_vectors(robot.exit_points_m[attached], position_m)
    feedback_tension = -feedback_torque_nm[attached] / robot.motor.drum_radius_m
    force = reference_tension_n @ u_reference + feedback_tension @ u_remaining
    remaining = np.full(u_remaining.shape[0], floor_n)
    free = np.ones(remaining.size, dtype=bool)
    while np.any(free):
        held_force = remaining[~free] @ u_remaining[~free]
        fit, *_ = np.linalg.lstsq(u_remaining[free].T, force - held_force, rcond=None)
        if np.min(fit) >= floor_n:
            remaining[free] = fit
            break
        free[np.flatnonzero(free)[np.argmin(fit)]] = False
    tensions = np.zeros(robot.cable_count)
    tensions[attached] = remaining
    return tensions


class Recovery:
    """Steps through the recovery phases, one control tick at a time.

    `setpoint(tick, angle, speed)` returns the mode and the setpoint for the next tick:
    tensions (N) in phase 1, a joint reference in phase 2, nothing in SAFE_HOLD.
    """

    def __init__(self, robot: Robot, config: RecoveryConfig, distribution: TensionDistribution,
                 period_s: float, attached: np.ndarray, start_tick: int,
                 start_tensions_n: np.ndarray):
        check_recoverable(robot, attached)
        self.robot = robot
        self.config = config
        self.distribution = distribution
        self.period_s = period_s
        self.attached = attached.copy()
        self.safe_point_m = safe_point_for(robot, config, attached)
        self.start_tensions_n = start_tensions_n
        self.safe_tensions_n = static_tensions(robot, self.safe_point_m, attached)
        if np.min(self.safe_tensions_n[attached]) <= 0.0:
            raise RecoveryInfeasible(f'SP {self.safe_point_m} is outside the residual workspace')
        self.start_tick = start_tick
        self.mode = RECOVERY_TENSION
        self.phase_ticks = {RECOVERY_TENSION: start_tick}
        self.move = None
        self.timed_out = False

    def tension_setpoint(self, tick: int) -> np.ndarray:
        """t(s) = t_R + (t_SP − t_R) s, s quintic over the tension phase (N)."""
        s, _, _ = quintic_profile((tick - self.start_tick) * self.period_s, self.config.tension_phase_s)
        return self.start_tensions_n + (self.safe_tensions_n - self.start_tensions_n) * s

    def settled(self, tick: int, angular_velocity_rad_s: np.ndarray) -> bool:
        elapsed = (tick - self.start_tick) * self.period_s
        if elapsed < self.config.tension_phase_s:
            return False
        if elapsed >= self.config.tension_phase_s + self.config.settle_timeout_s:
            self.timed_out = True
            return True
        return bool(np.max(np.abs(angular_velocity_rad_s[self.attached])) < self.config.settled_speed_rad_s)

    def plan_move(self, tick: int, angle_rad: np.ndarray, angular_velocity_rad_s: np.ndarray) -> None:
        """From the forward-kinematics pose and velocity to SP at rest, tabulated per tick.

        The move starts with the velocity the end-effector has (from the motors, eq. 17),
        so position control takes over without a jolt that could slacken a cable.
        """
        attached = self.attached
        start = forward_kinematics(self.robot, angle_rad, attached)
        u, _ = cable_vectors(self.robot.exit_points_m[attached], start)
        # l̇ = −S_Rᵀ ṗ = ρ θ̇  ⇒  ṗ = −(S_Rᵀ)⁺ ρ θ̇
        velocity, *_ = np.linalg.lstsq(
            u, -self.robot.motor.drum_radius_m * np.asarray(angular_velocity_rad_s)[attached], rcond=None)
        distance = float(np.linalg.norm(self.safe_point_m - start))
        duration = max(QUINTIC_PEAK_SPEED_RATIO * distance / self.config.move_peak_speed_m_s,
                       self.config.minimum_move_s)
        move = HermiteQuintic(start, velocity, self.safe_point_m, np.zeros(3), duration)
        self.move = (tick, tabulate_reference(
            self.robot, self.distribution, Sequence([move, Hold(self.safe_point_m, self.period_s)]),
            self.period_s, attached=attached))
        self.mode = RECOVERY_MOVE
        self.phase_ticks[RECOVERY_MOVE] = tick

    def setpoint(self, tick: int, angle_rad: np.ndarray, angular_velocity_rad_s: np.ndarray):
        """(mode, tensions or None, JointReference or None) for tick + 1."""
        if self.mode == RECOVERY_TENSION and self.settled(tick, angular_velocity_rad_s):
            self.plan_move(tick, angle_rad, angular_velocity_rad_s)
        if self.mode == RECOVERY_TENSION:
            return self.mode, self.tension_setpoint(tick + 1), None
        if self.mode == RECOVERY_MOVE:
            start, table = self.move
            row = tick + 1 - start
            if row >= len(table):
                self.mode = SAFE_HOLD
                self.phase_ticks[SAFE_HOLD] = tick + 1
                row = len(table) - 1
            return self.mode, None, JointReference(table.angle_rad[row], table.angular_velocity_rad_s[row],
                                                   table.feedforward_nm[row])
        return self.mode, None, None
