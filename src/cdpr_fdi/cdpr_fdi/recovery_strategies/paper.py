"""The paper's recovery (§3.2, docs/design.md §5), recovery.strategy `paper`: a point mass's
(3 DOF), the default of every point-mass robot.

"Taut" below: every remaining cable's static tension (eq. 22) at least `taut_tension_n`,
a fraction of an equal share of the weight.

Where the remaining cables hold the end-effector taut at detection, position control
takes over at once (RECOVERY_MOVE): a quintic that starts with its velocity, and with the
acceleration t_R gives it, brings it to rest, then a straight quintic takes it to SP,
under PD + feed-forward with S_R.

Elsewhere, phase 1 (RECOVERY_TENSION) first: a quintic in tension space from t_R, the
tensions that keep the force the robot applied at detection (eq. 23–25, no cable below
taut), to the static tensions of the *entry point*, the nearest point on the way to the
residual SEW's barycentre where the cables hold it taut. The paper aims at t_SP, the
static tensions at SP: constant tensions hold no position (along a cable they are
neutral), so the end-effector swings about the point they balance, and with SP a metre
away it swung out of the frame of a tall narrow robot. Aimed near it, it swings into the
residual SEW. Phase 2 (RECOVERY_MOVE) starts once the tension quintic has ended and the
end-effector — by the forward kinematics of the remaining cables — is held taut and
slower than `settle_speed_m_s`, or `settle_timeout_s` later.

A move whose tensions would come within `plan_tension_margin_n` of tension_min_n (what
the drives' tracking, and on a redundant robot the joints' position control, takes off a
planned tension) is planned again, braking sooner and moving slower; when no plan fits,
phase 1 holds the end-effector where it is and planning is tried again
`replan_interval_s` later (a plan takes tens of ms, more than a tick). At the timeout,
where no try keeps the margin still (a light end-effector settled where the cables left
hold it with little more than τ_min), the same tries with the margin lowered where a pose
needs it, never below τ_min (LoweredFloor), and a note says so; only when not even those
fit is the recovery given up (FAULT). Then SAFE_HOLD at SP.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.point_mass.kinematics import cable_vectors
from cdpr_control.model.reference_table import tabulate_reference
from cdpr_control.model.robot import Robot
from cdpr_control.point_mass.statics import static_tensions
from cdpr_control.tension_distribution import (InfeasibleTensionError, LoweredFloor, TensionDistribution,
                                               floored_fit, make_tension_distribution)
from cdpr_control.geometry.pose_trajectories import PoseTrajectory
from cdpr_control.geometry.trajectories import HermiteQuintic, Hold, Sequence, quintic_profile
from cdpr_control.point_mass.workspace import safe_point
from cdpr_msgs_py.contract import RECOVERY_MOVE, RECOVERY_TENSION, VERDICT_DELAY_TICKS

from ..recovery_planning.recovery import RecoveryInfeasible, check_recoverable, safe_point_for
from .base import Naming, RecoveryStrategy, TabulatedMove

# Bisection steps for the entry point: 2⁻²⁰ of the way to the barycentre.
ENTRY_BISECTIONS = 20


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
    tensions = np.zeros(robot.cable_count)
    tensions[attached] = floored_fit(u_remaining.T, force, floor_n)
    return tensions


def taut_tension_n(robot: Robot, config, attached: np.ndarray) -> float:
    """How taut (N) recovery keeps the remaining cables: `taut_fraction` of an equal share
    of the weight among them, at least `plan_tension_margin_n` above tension_min_n. Scaled
    by the load, not fixed: a floor tuned for one robot lifts a lighter end-effector (three
    cables at 5 N already carry 1.5 kg under near-vertical cables). The margin is phase
    2's: what a drive takes off a commanded tension — its drum's inertia as the
    end-effector swings about the entry point, its friction — phase 1's torques take off
    too (a light end-effector held at τ_min itself carried up to 0.5 N less for a second)."""
    share = robot.mass_kg * float(np.linalg.norm(robot.gravity_m_s2)) / np.count_nonzero(attached)
    return max(robot.tension_min_n + config.plan_tension_margin_n, config.taut_fraction * share)


def least_static_tension_n(robot: Robot, attached: np.ndarray, position_m) -> float:
    """The least static tension (N) of the `attached` cables at `position_m` (eq. 22);
    negative outside their static-equilibrium workspace."""
    return float(np.min(static_tensions(robot, position_m, attached)[attached]))


def entry_point(robot: Robot, attached: np.ndarray, position_m: np.ndarray,
                taut_n: float) -> np.ndarray:
    """Phase 1's point (m): `position_m` if the remaining cables hold it statically with
    every tension at least `taut_n`, else the first point that they do on the way from it
    to the barycentre of the residual SEW at its height (by bisection), else that
    barycentre."""
    position_m = np.asarray(position_m, dtype=float)
    if least_static_tension_n(robot, attached, position_m) >= taut_n:
        return position_m.copy()
    try:
        goal = safe_point(robot, attached, position_m[2])
    except ValueError as err:
        raise RecoveryInfeasible(f'no residual workspace at z = {position_m[2]:.3f} m: {err}') from None
    if least_static_tension_n(robot, attached, goal) < taut_n:
        return goal
    outside, inside = 0.0, 1.0
    for _ in range(ENTRY_BISECTIONS):
        middle = 0.5 * (outside + inside)
        if least_static_tension_n(robot, attached, position_m + middle * (goal - position_m)) >= taut_n:
            inside = middle
        else:
            outside = middle
    return position_m + inside * (goal - position_m)


class Recovery(TabulatedMove):
    """Steps through the paper's recovery phases, one control tick at a time.

    `setpoint(tick, angle, speed)` returns the mode and the setpoint for the tick the
    verdict on `tick` is due (tick + VERDICT_DELAY_TICKS):
    tensions (N) in phase 1, a joint reference in phase 2, nothing in SAFE_HOLD.
    Phase 1 goes from `start_tensions_n` (t_R) to the static tensions at
    `entry_point_m` (see `entry_point`); it is skipped when the end-effector was `inside`
    (the remaining cables held it taut) at detection.
    """

    def __init__(self, robot: Robot, config, distribution: TensionDistribution,
                 period_s: float, attached: np.ndarray, start_tick: int,
                 start_tensions_n: np.ndarray, entry_point_m: np.ndarray, inside: bool):
        check_recoverable(robot, attached)
        super().__init__()
        self.robot = robot
        self.config = config
        # Phase 2 plans with the configured method, its floor raised by the margin.
        self.distribution = make_tension_distribution(
            distribution.name, distribution.tension_min_n + config.plan_tension_margin_n,
            distribution.tension_max_n)
        # where no plan keeps that margin: as much of it as each pose allows
        self.lowered = LoweredFloor(self.distribution, distribution.tension_min_n)
        self.period_s = period_s
        self.attached = attached.copy()
        self.safe_point_m = safe_point_for(robot, config, attached)
        if np.min(static_tensions(robot, self.safe_point_m, attached)[attached]) <= 0.0:
            raise RecoveryInfeasible(f'SP {self.safe_point_m} is outside the residual workspace')
        self.start_tensions_n = start_tensions_n
        self.entry_point_m = np.asarray(entry_point_m, dtype=float)
        self.target_tensions_n = static_tensions(robot, self.entry_point_m, attached)
        self.taut_n = taut_tension_n(robot, config, attached)
        # Inside the residual SEW already, position control can hold the end-effector
        # from the first tick: phase 1 is skipped, the move starts with its velocity.
        self.tension_phase_s = 0.0 if inside else config.tension_phase_s
        self.start_tick = start_tick
        self.mode = RECOVERY_TENSION
        self.phase_ticks = {RECOVERY_TENSION: start_tick}
        self.move = None
        self.last_plan_error: InfeasibleTensionError | None = None
        # the first tick planning is tried again on after a plan that failed
        self.next_plan_tick = start_tick

    def tension_setpoint(self, tick: int) -> np.ndarray:
        """t(s) = t_R + (t_E − t_R) s, s quintic over the tension phase (N)."""
        s, _, _ = quintic_profile((tick - self.start_tick) * self.period_s, self.config.tension_phase_s)
        return self.start_tensions_n + (self.target_tensions_n - self.start_tensions_n) * s

    def swing_damping_n(self, position_m, velocity_m_s) -> np.ndarray:
        """Tensions (N, remaining cables, least squares) of the force −c ṗ that damps the
        end-effector's swing: c = 2 ζ m √(g / d̄), the pendulum on the mean remaining cable
        length d̄ critically damped at ζ = 1."""
        directions, lengths = cable_vectors(self.robot.exit_points_m[self.attached], position_m)
        gravity = float(np.linalg.norm(self.robot.gravity_m_s2))
        damping = (2.0 * self.config.swing_damping_ratio * self.robot.mass_kg
                   * np.sqrt(gravity / float(np.mean(lengths))))
        tensions, *_ = np.linalg.lstsq(directions.T, -damping * np.asarray(velocity_m_s), rcond=None)
        return tensions

    def damped_tension_setpoint(self, tick: int, state) -> np.ndarray:
        """Phase 1's setpoint with the swing damping of the end-effector's `state`
        (position, velocity; None where its pose cannot be found: no damping) added,
        scaled down as far as needed to keep every tension within [taut, τ_max] (never
        raised to taut where the quintic itself is below it): clipping cable by cable would
        turn the force away from −ṗ, and on a light robot pull a cable slack."""
        tensions = self.tension_setpoint(tick)
        if self.config.swing_damping_ratio == 0.0 or state is None:
            return tensions
        attached = tensions[self.attached]
        damping = self.swing_damping_n(*state)
        # the largest s in [0, 1] with lower <= attached + s damping <= upper
        bound = np.where(damping < 0.0, np.minimum(attached, self.taut_n),
                         np.maximum(attached, self.robot.tension_max_n))
        acting = damping != 0.0
        scale = float(np.clip(np.min((bound - attached)[acting] / damping[acting], initial=1.0), 0.0, 1.0))
        tensions[self.attached] = attached + scale * damping
        return tensions

    def end_effector_state(self, angle_rad, angular_velocity_rad_s):
        """Position (m, forward kinematics of the remaining cables) and velocity (m/s):
        l̇ = −S_Rᵀ ṗ = ρ θ̇  ⇒  ṗ = −(S_Rᵀ)⁺ ρ θ̇ (eq. 17)."""
        position, _ = self.pose(angle_rad)
        u, _ = cable_vectors(self.robot.exit_points_m[self.attached], position)
        velocity, *_ = np.linalg.lstsq(
            u, -self.robot.motor.drum_radius_m * np.asarray(angular_velocity_rad_s)[self.attached],
            rcond=None)
        return position, velocity

    def planning_due(self, tick: int) -> bool:
        """The tension quintic has ended (at once when phase 1 is skipped)."""
        return (tick - self.start_tick) * self.period_s >= self.tension_phase_s

    def settled(self, tick: int, position_m, velocity_m_s) -> bool:
        """Phase 2 may start: inside the residual SEW and slow enough, or timed out."""
        elapsed = (tick - self.start_tick) * self.period_s
        if elapsed >= self.tension_phase_s + self.config.settle_timeout_s:
            self.timed_out = True
            return True
        return (least_static_tension_n(self.robot, self.attached, position_m) >= self.taut_n
                and float(np.linalg.norm(velocity_m_s)) < self.config.settle_speed_m_s)

    def plan_move(self, tick: int, start_m: np.ndarray, velocity_m_s: np.ndarray,
                  acceleration_m_s2: np.ndarray) -> bool:
        """From the end-effector's position, velocity and acceleration to SP at rest,
        tabulated per tick; False when no plan keeps the tensions within the bounds.

        A moving end-effector is first brought to rest on its way (a quintic that starts
        with its velocity and acceleration, so position control takes over without a
        step in the cables' tensions that could slacken one), then moved to SP in a
        straight line. Where the tensions of a plan would leave the bounds, it is planned
        again, braking `replan_slowdown` times sooner (nearer where it is) and moving that
        much slower, at most `replan_attempts` times; then as often from no acceleration
        (the tensions stepping to the plan's). A failed planning is not tried again before
        `replan_interval_s` has passed; once phase 1 has timed out, where none keeps the
        planned margin, the same tries with it lowered where a pose needs it (module
        docstring).
        """
        if tick < self.next_plan_tick and not self.timed_out:
            return False
        brake_s = self.config.brake_s(float(np.linalg.norm(velocity_m_s)))
        for distribution in (self.distribution, self.lowered) if self.timed_out else (self.distribution,):
            # from rest in acceleration once: a plan that asks none is not tried twice
            for acceleration in ((acceleration_m_s2, np.zeros(3)) if np.any(acceleration_m_s2)
                                 else (acceleration_m_s2,)):
                for attempt in range(self.config.replan_attempts + 1):
                    slowdown = self.config.replan_slowdown ** attempt
                    trajectory = PoseTrajectory(self.move_to_safe_point(
                        start_m, velocity_m_s, acceleration, brake_s / slowdown, slowdown))
                    try:
                        # a try whose first row no tensions pull fails with that row's error
                        # whatever follows: found in one row, not in thousands
                        tabulate_reference(self.robot, distribution, trajectory, self.period_s, duration_s=0.0,
                                           attached=self.attached)
                        table = tabulate_reference(self.robot, distribution, trajectory, self.period_s,
                                                   attached=self.attached)
                    except InfeasibleTensionError as err:
                        # the margin's reason: the lowered floor's only says no plan holds τ_min
                        if distribution is self.distribution:
                            self.last_plan_error = err
                        continue
                    self.bounded_table(table)
                    if distribution is self.lowered:
                        self.notes.append(
                            f'the move to SP cannot keep the planned tension margin ({self.last_plan_error}): '
                            f'planned with the margin each pose allows, the least tension '
                            f'{table.tension_n[:, self.attached].min():.2f} N')
                    self.move = (tick, table)
                    self.mode = RECOVERY_MOVE
                    self.phase_ticks[RECOVERY_MOVE] = tick
                    return True
        self.next_plan_tick = tick + max(round(self.config.replan_interval_s / self.period_s), 1)
        return False

    def replan(self, tick: int, angle_rad, angular_velocity_rad_s) -> None:
        """The move to SP planned again from where the motors say the end-effector is
        (StartedRecovery.replan; RecoveryInfeasible where no plan holds), RECOVERY_MOVE
        still dated from the first move."""
        position, velocity = self.end_effector_state(angle_rad, angular_velocity_rad_s)
        started, self.next_plan_tick = self.phase_ticks.get(RECOVERY_MOVE, tick), tick
        if not self.plan_move(tick, position, velocity, np.zeros(3)):
            raise self.last_plan_error or RecoveryInfeasible('no move to SP from where the move ended')
        self.phase_ticks[RECOVERY_MOVE] = started

    def acceleration_m_s2(self, position_m: np.ndarray, tensions_n: np.ndarray) -> np.ndarray:
        """p̈ = (S_R t_R + m g) / m: what the remaining cables' tensions (N) do to the
        end-effector at `position_m`."""
        directions, _ = cable_vectors(self.robot.exit_points_m[self.attached], position_m)
        return tensions_n[self.attached] @ directions / self.robot.mass_kg + self.robot.gravity_m_s2

    def move_to_safe_point(self, start_m, velocity_m_s, acceleration_m_s2, brake_s: float,
                           slowdown: float) -> Sequence:
        """Brake over `brake_s` (to where the end-effector then is, half its speed times
        that time ahead), then a straight quintic to SP at the peak speed / `slowdown`."""
        rest = start_m + 0.5 * brake_s * np.asarray(velocity_m_s)
        segments = [HermiteQuintic(start_m, velocity_m_s, rest, np.zeros(3), brake_s,
                                   acceleration_m_s2)]
        distance = float(np.linalg.norm(self.safe_point_m - rest))
        if distance > self.config.reached_tolerance_m:
            duration = self.config.move_s(distance) * slowdown
            segments.append(HermiteQuintic(rest, np.zeros(3), self.safe_point_m, np.zeros(3), duration))
        else:
            segments[0] = HermiteQuintic(start_m, velocity_m_s, self.safe_point_m, np.zeros(3), brake_s,
                                         acceleration_m_s2)
        return Sequence(segments + [Hold(self.safe_point_m, self.period_s)])

    def tabulated(self) -> tuple[int, object]:
        return self.move

    def setpoint(self, tick: int, angle_rad: np.ndarray, angular_velocity_rad_s: np.ndarray):
        """(mode, tensions or None, JointReference or None) for tick + VERDICT_DELAY_TICKS."""
        state = None
        if self.mode == RECOVERY_TENSION and self.planning_due(tick):
            state = position, velocity = self.end_effector_state(angle_rad, angular_velocity_rad_s)
            if self.tension_phase_s == 0.0:
                # with the acceleration t_R gives it: the cables' tensions go on
                if not self.plan_move(tick, position, velocity,
                                      self.acceleration_m_s2(position, self.start_tensions_n)):
                    # no plan from where it is: hold it there by tension until it settles
                    self.tension_phase_s = self.config.tension_phase_s
            # After phase 1, from no acceleration: its last tensions hold some cable at the
            # taut floor as the end-effector swings about the entry point, the static ones
            # of where it is are further from it (going on from phase 1's left a cable
            # under τ_min for a period at the switch in 13 of 192 runs of the tall frame).
            elif (self.settled(tick, position, velocity)
                  and not self.plan_move(tick, position, velocity, np.zeros(3))):
                if self.timed_out:
                    raise self.last_plan_error
        if self.mode == RECOVERY_TENSION:
            if state is None and self.config.swing_damping_ratio > 0.0:
                # the swing damping needs the pose before planning is due; a tick where it
                # cannot be found goes undamped (planning, when due, raises instead)
                try:
                    state = self.end_effector_state(angle_rad, angular_velocity_rad_s)
                except (ValueError, np.linalg.LinAlgError):
                    state = None
            return self.mode, self.damped_tension_setpoint(tick + VERDICT_DELAY_TICKS, state), None
        if self.mode == RECOVERY_MOVE:
            reference = self.move_setpoint(tick)
            return self.mode, None, reference
        return self.mode, None, None


class Paper(RecoveryStrategy):
    """The paper's recovery of a point mass (module docstring), from the position the
    remaining cables give at the naming and the force the robot applied then."""

    name = 'paper'
    degrees_of_freedom = 3
    description = ('a tension-space quintic towards the residual workspace, then a move to SP under '
                   'position control (the paper\'s)')

    def start(self, naming: Naming) -> Recovery:
        robot, config, attached = naming.robot, naming.config, naming.attached
        tracker, (position, _) = naming.named_pose()
        taut = taut_tension_n(robot, config, attached)
        entry = entry_point(robot, attached, position, taut)
        reference, reference_pose = naming.reference, naming.reference_pose()
        if reference_pose is None:
            raise RecoveryInfeasible('the reference angles of the naming tick fit no position')
        start = initial_tensions(robot, position, attached, reference_pose[0],
                                 naming.reference_tensions_n, naming.command_nm - reference.feedforward_nm, taut)
        recovery = Recovery(robot, config, naming.distribution, naming.period_s, attached, naming.tick, start,
                            entry, inside=bool(np.all(entry == position)))
        recovery.tracker = tracker
        return recovery
