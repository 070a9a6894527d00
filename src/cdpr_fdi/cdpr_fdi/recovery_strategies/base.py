"""The interface of a recovery strategy (docs/recovery-strategies.md).

A `RecoveryStrategy` has a name (the value of recovery.strategy that chooses it), the
degrees of freedom of the end-effectors it recovers (`Robot.degrees_of_freedom`), what it
prepares when the supervisor is built (kernels to load, safe poses to find: the naming
tick has no time for them), and `start`, which the supervisor calls on the naming tick
with what it has then (`Naming`). The `StartedRecovery` it returns is stepped by the
supervisor on every tick after (`step`), until SAFE_HOLD or FAULT; the supervisor asks it
nothing else, and nothing of the kind of end-effector.

What every started recovery shares is here, written once (docs/detection-and-recovery.md):

- its poses from the motors, forward kinematics of the attached cables that falls back
  where it does not converge (cdpr_control.model.pose_tracking; `pose`), said in a note
  and counted in the summary (`kinematics_fallbacks`);
- SAFE_HOLD only at the safe pose (`step`): where a strategy's move has ended, the
  motors' pose must be within `reached_tolerance_m` of the safe point and, on a
  platform, `reached_tolerance_deg` of the safe orientation; the end held up to
  `hold_settle_s` to get there, else re-planned from where it is (`replan`, the
  strategy's) up to `hold_replan_attempts` times, else HeldOffSafePose (FAULT, "held
  X m / Y° from the safe pose"); the error in the summary (`hold_error_m`, `hold_error_deg`);
- commanded tensions within [τ_min, τ_max] of the robot (`bounded`, `bounded_table`),
  a note where they were clipped.

`config` below is the robot's cdpr_fdi.settings.config.RecoveryConfig, passed on as it is: that
module reads recovery.strategy against this package's strategies, so nothing here
imports it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cdpr_control.control.controller import JointReference
from cdpr_control.model.body import KinematicsError
from cdpr_control.model.pose_tracking import PoseTracker
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import TensionDistribution
from cdpr_control.tension_distribution.base import BOUND_TOLERANCE_N
from cdpr_msgs_py.contract import RECOVERY_MOVE, SAFE_HOLD, VERDICT_DELAY_TICKS

from ..recovery_planning.recovery import RecoveryInfeasible, find_safe_targets


class HeldOffSafePose(RecoveryInfeasible):
    """A recovery's move ended off the safe pose, and re-planning did not bring it there."""


@dataclass(frozen=True)
class Naming:
    """What the supervisor has on the tick it names the broken cables: the robot, its
    recovery settings (`config`), the controller's tension distribution, the control
    period, the planner of a realtime node (cdpr_fdi.recovery_planning.planning; None: plan at once), the
    naming `tick`, the `attached` cables (a boolean mask), the measured motor angles and
    speeds, the torques commanded on the tick (N·m), the tick's joint reference, and the
    tensions that reference asks for (N; supervisor.reference_tensions)."""

    robot: Robot
    config: object
    distribution: TensionDistribution
    period_s: float
    planner: object | None
    tick: int
    attached: np.ndarray
    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    command_nm: np.ndarray
    reference: JointReference
    reference_tensions_n: np.ndarray

    def named_pose(self) -> tuple[PoseTracker, tuple]:
        """The recovery's pose tracker and the pose (position m, orientation) the attached
        cables' motor angles give on the naming tick, its fallback started from the
        reference pose of the tick (all cables)."""
        tracker = PoseTracker(self.robot, self.attached, self.config.kinematics_fallback_iterations)
        return tracker, tracker.pose(self.angle_rad, self.reference_pose())

    def reference_pose(self) -> tuple | None:
        """(position m, orientation) of the tick's joint reference, every cable's angle;
        None where forward kinematics finds none."""
        try:
            return self.robot.body.pose_of_angles(self.robot, self.reference.angle_rad)
        except KinematicsError:
            return None


class StartedRecovery:
    """A recovery under way. Each has `safe_point_m` (where it takes the end-effector),
    `phase_ticks` (mode → the tick it began on), `timed_out` (whether a phase ended by its
    timeout rather than by its condition) and notes to say once; a subclass sets `robot`,
    `config`, `period_s`, `attached` and `mode`, and (a platform's) `safe_orientation`.
    The supervisor steps it by `step` (module docstring), which asks the subclass's
    `setpoint` and, where a move ended off the safe pose, its `replan`."""

    safe_point_m: np.ndarray
    phase_ticks: dict[str, int]
    safe_orientation = None

    def __init__(self):
        self.timed_out = False
        self.notes: list[str] = []
        self.tracker: PoseTracker | None = None
        self.kinematics_noted = False
        self.clip_noted = False
        # the tick from which a move's end is held to settle onto the safe pose (None: not now)
        self.hold_since: int | None = None
        self.held_reference: JointReference | None = None
        self.hold_confirmed = False
        self.hold_replans = 0
        # (m, deg) from the safe pose where the last move's end was judged
        self.hold_error: tuple[float, float] | None = None

    @property
    def kinematics(self) -> PoseTracker:
        """The recovery's pose tracker (Naming.named_pose's where the strategy kept it)."""
        if self.tracker is None:
            self.tracker = PoseTracker(self.robot, self.attached, self.config.kinematics_fallback_iterations)
        return self.tracker

    def pose(self, angle_rad, hint=None) -> tuple:
        """(position m, orientation) of the attached cables' motor angles, falling back
        where forward kinematics does not converge (noted once, take_notes)."""
        return self.kinematics.pose(angle_rad, hint)

    def note_kinematics(self) -> None:
        """The first fallback of the pose tracker (the naming's too), noted once."""
        if self.tracker is not None and self.tracker.fallbacks and not self.kinematics_noted:
            self.kinematics_noted = True
            self.notes.append(f'forward kinematics did not converge ({self.kinematics.first_error}): fell back '
                              f'on {self.config.kinematics_fallback_iterations} steps from a better start, '
                              f'else the last pose found (kinematics_fallbacks in the summary)')

    def pose_error(self, angle_rad) -> tuple[float, float]:
        """(m, deg) from the motors' pose (the attached cables') to the safe pose."""
        position, orientation = self.pose(angle_rad)
        angle = self.robot.body.orientation_error_rad(orientation, self.safe_orientation)
        return float(np.linalg.norm(np.asarray(position) - self.safe_point_m)), math.degrees(angle)

    def step(self, tick: int, angle_rad, angular_velocity_rad_s
             ) -> tuple[str, np.ndarray | None, JointReference | None]:
        """`setpoint`, its tensions `bounded`, and SAFE_HOLD only at the safe pose (module
        docstring): while a move's end is held to settle, RECOVERY_MOVE and its last
        reference; HeldOffSafePose where it is not reached."""
        config = self.config
        if self.hold_since is None:
            mode, tensions, reference = self.setpoint(tick, angle_rad, angular_velocity_rad_s)
            tensions = self.bounded(tensions)
            if mode != SAFE_HOLD or self.hold_confirmed:
                return mode, tensions, reference
            # the strategy's move has ended: judged from here
            self.hold_since, self.held_reference = tick, reference
            self.mode = RECOVERY_MOVE
            self.phase_ticks.pop(SAFE_HOLD, None)
        distance_m, angle_deg = self.hold_error = self.pose_error(angle_rad)
        if distance_m <= config.reached_tolerance_m and angle_deg <= config.reached_tolerance_deg:
            self.hold_since, self.hold_confirmed, self.mode = None, True, SAFE_HOLD
            self.phase_ticks[SAFE_HOLD] = tick + VERDICT_DELAY_TICKS
            return SAFE_HOLD, None, self.held_reference
        if (tick - self.hold_since) * self.period_s < config.hold_settle_s:
            return RECOVERY_MOVE, None, self.held_reference
        self.hold_since = None
        where = f'{distance_m:.3g} m / {angle_deg:.3g}° from the safe pose'
        if self.hold_replans >= config.hold_replan_attempts:
            raise HeldOffSafePose(f'held {where}' + (f' after {self.hold_replans} re-plan(s) of the move'
                                                     if self.hold_replans else ''))
        self.hold_replans += 1
        self.notes.append(f'the move ended {where} (tolerance {config.reached_tolerance_m:g} m / '
                          f'{config.reached_tolerance_deg:g}°): re-planned from where it is '
                          f'({self.hold_replans} of {config.hold_replan_attempts})')
        try:
            self.replan(tick, angle_rad, angular_velocity_rad_s)
        except (RecoveryInfeasible, ValueError) as err:
            raise HeldOffSafePose(f'held {where}, and no move from there: {err}') from None
        return self.step(tick, angle_rad, angular_velocity_rad_s)

    def replan(self, tick: int, angle_rad, angular_velocity_rad_s) -> None:
        """A move to the safe pose from where the motors say the end-effector is, from
        the tick the verdict on `tick` is due (mode RECOVERY_MOVE); RecoveryInfeasible
        where the strategy has none."""
        raise RecoveryInfeasible('the strategy re-plans no move')

    def bounded(self, tensions: np.ndarray | None) -> np.ndarray | None:
        """Tension setpoints (N) with the attached cables' within [τ_min, τ_max] (noted once
        where they were not)."""
        if tensions is None:
            return None
        clipped = self.clip_n(tensions[self.attached], 'tension setpoints')
        if clipped is None:
            return tensions
        tensions = np.array(tensions, dtype=float)
        tensions[self.attached] = clipped
        return tensions

    def bounded_table(self, table):
        """A tabulated move (model.reference_table) with the attached cables' planned
        tensions within [τ_min, τ_max], the feed-forward torques moved with them (c = −ρ t
        in the tension's part; noted once where they were not); the table itself."""
        clipped = self.clip_n(table.tension_n[:, self.attached], 'planned tensions')
        if clipped is not None:
            change = clipped - table.tension_n[:, self.attached]
            table.tension_n[:, self.attached] = clipped
            table.feedforward_nm[:, self.attached] -= self.robot.motor.drum_radius_m * change
        return table

    def clip_n(self, tensions: np.ndarray, what: str) -> np.ndarray | None:
        """`tensions` (N) clipped to the robot's [τ_min, τ_max]; None where they are within
        (to BOUND_TOLERANCE_N)."""
        low, high = self.robot.tension_min_n, self.robot.tension_max_n
        if tensions.size == 0 or (tensions.min() >= low - BOUND_TOLERANCE_N
                                  and tensions.max() <= high + BOUND_TOLERANCE_N):
            return None
        if not self.clip_noted:
            self.clip_noted = True
            self.notes.append(f'{what} of {tensions.min():.2f}–{tensions.max():.2f} N clipped to '
                              f'[{low:g}, {high:g}] N (said once)')
        return np.clip(tensions, low, high)

    def setpoint(self, tick: int, angle_rad, angular_velocity_rad_s
                 ) -> tuple[str, np.ndarray | None, JointReference | None]:
        """(mode, tensions N or None, joint reference or None) for the tick the verdict on
        `tick` is due (tick + VERDICT_DELAY_TICKS), from the motors' measured angles and
        speeds; RecoveryInfeasible (or ValueError) where the recovery is given up."""
        raise NotImplementedError

    def planned_references(self, tick: int, count: int, due_tick: int | None = None
                           ) -> list[tuple[int, JointReference]]:
        """(tick, joint reference) of the `count` ticks after tick + VERDICT_DELAY_TICKS
        that the recovery already fixes (supervisor.planned_references)."""
        raise NotImplementedError

    def take_notes(self) -> list[str]:
        """What the recovery gave up, or how its plans came late, each said once."""
        self.note_kinematics()
        notes, self.notes = self.notes, []
        return notes

    def summary(self) -> dict:
        """What it adds to the supervisor's summary, in plain types: the forward
        kinematics' fallbacks, where the last move's end was judged from the safe pose
        (m, deg; None before), the re-plans that took; a subclass's on top."""
        error = self.hold_error
        return {'kinematics_fallbacks': 0 if self.tracker is None else self.tracker.fallbacks,
                'hold_error_m': None if error is None else error[0],
                'hold_error_deg': None if error is None else error[1],
                'hold_replans': self.hold_replans}


class RecoveryStrategy:
    """A way to recover the end-effector after a break (module docstring). A subclass sets
    `name`, `degrees_of_freedom` and `description` (a line for cdpr-robot), and gives
    `start`; `prepare` where it needs something ready before a cable breaks."""

    name: str
    degrees_of_freedom: int
    description: str
    # it may steer the end-effector (its approach's time limit then bounds how long a
    # recovery may take: RecoveryConfig.budget_s)
    steers = False

    def prepare(self, robot: Robot, config) -> None:
        """Make ready, when the supervisor is built, what `start` would not have the time
        for on the naming tick: the safe target after each single break (a point mass's
        SP searched on a grid where the paper's is not held)."""
        find_safe_targets(robot, config)

    def start(self, naming: Naming) -> StartedRecovery:
        """The recovery from the naming tick on; RecoveryInfeasible (or ValueError) where
        it cannot start (the supervisor holds the drums: FAULT)."""
        raise NotImplementedError


def table_reference(table, row: int) -> JointReference:
    """The joint reference of a tabulated move's `row`."""
    return JointReference(table.angle_rad[row], table.angular_velocity_rad_s[row], table.feedforward_nm[row])


class TabulatedMove(StartedRecovery):
    """A recovery's move to its safe point, tabulated per tick from a start tick; the
    recovery (its `mode` and `phase_ticks`) enters SAFE_HOLD on the tick the move ends.
    A subclass says which table it follows (`tabulated`)."""

    mode: str

    def tabulated(self) -> tuple[int, object]:
        """(start tick, table) of the move under way."""
        raise NotImplementedError

    def move_setpoint(self, tick: int) -> JointReference:
        """The joint reference of the tick the verdict on `tick` is due (tick +
        VERDICT_DELAY_TICKS): the table's row, its last on the tick SAFE_HOLD starts."""
        start_tick, table = self.tabulated()
        due = tick + VERDICT_DELAY_TICKS
        row = due - start_tick
        if row >= len(table):
            self.mode = SAFE_HOLD
            self.phase_ticks[SAFE_HOLD] = due
            row = len(table) - 1
        return table_reference(table, row)

    def planned_references(self, tick: int, count: int, due_tick: int | None = None) -> list[tuple[int, JointReference]]:
        """(tick, joint reference) of the `count` ticks after the one the verdict on `tick`
        is due (tick + VERDICT_DELAY_TICKS) that the move under
        way already fixes, as far as its table goes; none outside RECOVERY_MOVE. A point
        mass's move is tabulated whole when it starts: nothing waits for `due_tick`
        (braked.PoseRecovery's does)."""
        if self.mode != RECOVERY_MOVE:
            return []
        start_tick, table = self.tabulated()
        first = tick + VERDICT_DELAY_TICKS + 1 - start_tick
        return [(start_tick + row, table_reference(table, row))
                for row in range(max(first, 0), min(first + count, len(table)))]
