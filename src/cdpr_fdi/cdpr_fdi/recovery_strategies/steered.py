"""A platform's recovery steered to its safe pose, recovery.strategy `steered` (issue 29;
docs/platform.md): after every break, the default of every platform robot; and with
`braked` where no static tensions of the remaining cables within [τ_min, τ_max] hold the
platform at its pose at the naming, so that it cannot be braked to rest there.

The platform is steered by cdpr_control.platform.steered_approach, under tensions kept
`approach_tension_margin_n` above τ_min (at most `approach_safe_margin_share` of the safe
pose's own tension margin), its orientation pulled hard, its position let
move as those tensions allow. The steered motion is tabulated per tick for the drives
(its wrench shared again by the recovery's distribution), stepped as the ticks ask for
it, so that a realtime supervisor plans a few rows at a time; from where the naming
tick's torques take the platform (platform.after_the_naming_tick), its first row
eased in from them (ease_in). Once the platform is within `approach_arrival_m` and
`approach_arrival_deg` of the safe pose, nearly at rest, it is held there (SAFE_HOLD).

A steered motion that turns the platform more than `approach_turn_limit_deg` further from
the safe orientation than it was at the naming (its cables would wind about it), or does
not arrive within `approach_limit_s`, is not waited for: the approach is stepped ahead
to its end by the recovery's planner (at once where it has none; on a realtime
supervisor's planning thread, while the rows are sent), and where it would fail it is
steered again from the row then under way, at most `replan_attempts` times, each try
stepped ahead in turn; a note says so. A try steered again keeps its tensions above
τ_min by at most `approach_safe_margin_share` of the least margin of the poses its own
aim schedule turns the platform to on its way: tensions further above τ_min than those
that hold the platform on its way cannot hold it there (a drawn 5.6 kg platform named
16 cm from its safe pose, held there 1.4 N above τ_min, was pulled up to the frame's
top by tensions 4 N above and turned 30°, pulled at any speed; a drawn 2.9 kg crossed
one was swung about the frame for 15 s). The first try keeps the safe pose's share (its
way's, on the shipped platform, left elastic cables ringing below τ_min). Each try is
pulled `replan_slowdown` times slower than the one before (a platform spun by the break
turns further while it is pulled fast across the frame: the loop of a drawn 12 kg
platform, cable 3 at 19 %, turned 25° and reached its safe pose pulled at 1 rad/s, not
1.5), but the first whose margin that lowers, pulled as fast (slow_down). One that still
turns too far, or has not arrived within `approach_limit_s`, is given up:
RecoveryInfeasible, so the supervisor holds the drums (FAULT) and says why.
"""
from __future__ import annotations

import dataclasses
import math

import numpy as np

from cdpr_control.control.controller import JointReference
from cdpr_control.model.dynamics import inverse_dynamics
from cdpr_control.model.reference_table import ReferenceTable, table_of
from cdpr_control.geometry.pose_trajectories import PoseSample
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import normalised
from cdpr_control.platform.steered_approach import AimSchedule, ApproachGains, SteeredApproach, aim_schedule
from cdpr_control.tension_distribution import FlooredLeastSquares, TensionDistribution
from cdpr_msgs_py.contract import RECOVERY_MOVE, SAFE_HOLD, VERDICT_DELAY_TICKS

from ..recovery_planning.planning import PlanAtOnce
from ..recovery_planning.recovery import RecoveryInfeasible
from .base import Naming, RecoveryStrategy, table_reference
from .platform import (PlatformRecovery, after_the_naming_tick, ease_in, moving_state, named_state,
                       prepare_platform)

# Rows are stepped and tabulated this many at a time (the rows do not depend on it): a
# realtime supervisor's tick is held up ~0.35 ms once every ten ticks for them (~0.27 ms of
# it numpy's per-call cost, the same for two rows: two at a time cost four times the CPU;
# docs/platform.md).
ROWS_PER_STEP = 10
# A try is stepped ahead this many rows at a time (its rows do not depend on it).
ROWS_PER_LOOK_AHEAD = 500


class PoseApproach(PlatformRecovery):
    """Steps through a platform's steered approach to its safe pose, one control tick at a
    time, as braked.PoseRecovery does a braked one (module docstring)."""

    def __init__(self, robot: Robot, config, distribution: TensionDistribution,
                 period_s: float, attached: np.ndarray, start_tick: int, position_m, orientation,
                 velocity_m_s, angular_velocity_rad_s, command_nm, planner=None):
        """From the pose and twist the remaining (`attached`) cables give at detection and
        the torques (N·m) commanded on that tick, each try stepped ahead by `planner`
        (planning.py; at once when None); RecoveryInfeasible where there is no safe
        pose."""
        super().__init__(robot, config, distribution, period_s, attached, start_tick)
        # the steered wrench is pulled by tensions above the margin: the floored fit never
        # acts but on a rounding at a bound
        self.distribution = FlooredLeastSquares(self.lowered)
        self.command_nm = np.asarray(command_nm, dtype=float)
        self.eased = False
        start = after_the_naming_tick(robot, self.attached, np.asarray(position_m, dtype=float),
                                      normalised(orientation), np.asarray(velocity_m_s, dtype=float),
                                      np.asarray(angular_velocity_rad_s, dtype=float), self.command_nm, period_s)
        self.planner = planner or PlanAtOnce()
        self.row_limit = math.ceil(config.approach_limit_s / period_s)
        self.steer_from(start)
        self.notes.append('steered to the safe pose under tensions within their bounds')

    def steer_from(self, start: PoseSample) -> None:
        """The approach from the state `start` on the row first_tick, with the configured
        pull, stepped ahead by the planner, tabulated as asked."""
        config = self.config
        # the try under way, the row of the recovery its first row is, its gains and the
        # margin (N) above τ_min its tensions keep
        self.gains, self.approach_row = config.approach_gains, 0
        self.margin_n = self.margin_within(self.safe_margin_n)
        self.approach = self.steered(start, self.gains, self.margin_n)
        self.turn_limit_rad = (self.approach.errors(self.approach.samples(0, 1))[1][0]
                               + math.radians(config.approach_turn_limit_deg))
        # tries steered again, and whether one of them lowered the margin (slow_down)
        self.slowdowns, self.lowered = 0, False
        # whether the try under way, stepped ahead to its end, fails (a Future)
        self.look_ahead = self.planner.submit(self.fails, start, self.gains, self.margin_n, 0, self.approach.aim,
                                              urgent=True)
        self.tables: list[ReferenceTable] = []
        self.arrival_row: int | None = None
        self.hold: JointReference | None = None

    def replan(self, tick: int, angle_rad, angular_velocity_rad_s) -> None:
        """Steered again from where the motors say the platform is, from the tick the
        verdict on `tick` is due (StartedRecovery.replan), its first row not eased in (the
        drives hold the last reference)."""
        position, orientation, velocity, angular_velocity = moving_state(
            self.robot, angle_rad, angular_velocity_rad_s, self.attached, self.pose(angle_rad))
        zero = np.zeros(3)
        self.first_tick = tick + VERDICT_DELAY_TICKS
        self.eased = True
        self.steer_from(PoseSample(np.asarray(position, dtype=float), normalised(orientation),
                                   np.asarray(velocity, dtype=float), np.asarray(angular_velocity, dtype=float),
                                   zero, zero))
        self.mode = RECOVERY_MOVE

    def margin_within(self, held_n: float) -> float:
        """The margin (N) above τ_min a try keeps its tensions at, where the poses it is to
        hold the platform at are held `held_n` above τ_min: approach_tension_margin_n, at
        most approach_safe_margin_share of `held_n` (tensions kept further above τ_min
        than those that hold the platform there cannot hold it there: a light platform's
        cables pulled it up, past its safe pose, to the frame)."""
        config = self.config
        return min(config.approach_tension_margin_n, config.approach_safe_margin_share * held_n)

    def steered(self, start: PoseSample, gains: ApproachGains, margin_n: float,
                aim: AimSchedule | None = None) -> SteeredApproach:
        """A try from `start` to the safe pose with the pull `gains`, its tensions kept
        `margin_n` above τ_min (and the aim schedule made from `start`, where it has been)."""
        return SteeredApproach(self.robot, self.attached, start, self.safe_point_m, self.safe_orientation, gains,
                               self.robot.tension_min_n + margin_n, self.robot.tension_max_n, self.period_s, aim)

    def fails(self, start: PoseSample, gains: ApproachGains, margin_n: float, first_row: int,
              aim: AimSchedule) -> bool:
        """Whether the try from `start` (the recovery's row `first_row`) with `gains`, its
        tensions `margin_n` above τ_min and the aim schedule `aim` its approach made,
        stepped ahead on a copy of its own, turns the platform further than the limit
        before it arrives, or does not arrive before the time limit."""
        probe = self.steered(start, gains, margin_n, aim)
        for row in range(0, self.row_limit - first_row, ROWS_PER_LOOK_AHEAD):
            sample = probe.samples(row, row + ROWS_PER_LOOK_AHEAD)
            turned = np.flatnonzero(probe.errors(sample)[1] > self.turn_limit_rad)
            arrived = self.arrivals(probe, sample)
            if turned.size and (not arrived.size or turned[0] < arrived[0]):
                return True
            if arrived.size:
                return False
        return True

    def arrivals(self, approach: SteeredApproach, sample: PoseSample) -> np.ndarray:
        """The rows of `sample` (offsets) where the platform has arrived at the safe pose."""
        distance_m, angle_rad, speed_m_s, angular_speed_rad_s = approach.errors(sample)
        config, gains = self.config, self.config.approach_gains
        arrival_rad = math.radians(config.approach_arrival_deg)
        return np.flatnonzero((distance_m <= config.approach_arrival_m) & (angle_rad <= arrival_rad)
                              & (speed_m_s <= gains.position_frequency_rad_s * config.approach_arrival_m)
                              & (angular_speed_rad_s <= gains.orientation_frequency_rad_s * arrival_rad))

    def tabulated_rows(self) -> int:
        return len(self.tables) * ROWS_PER_STEP

    def slow_down(self, row: int) -> None:
        """Where the look ahead found the try under way to fail: steer again from the
        recovery's row `row`, the tensions kept no further above τ_min than the poses on
        the new try's way allow (margin_within), the position pulled `replan_slowdown`
        times slower than the try before, but for the first try whose margin that lowers:
        pulled as fast (a drawn 9.8 kg platform's approach, kept 2.2 N above τ_min instead
        of 4.3, reached its safe pose pulled at 1.5 rad/s, and was flung across the frame
        at 1, 0.67 and 0.44); and step that try ahead in turn (none after
        `replan_attempts`: the try under way goes on, and its check gives the recovery
        up)."""
        if (self.look_ahead is None or not self.look_ahead.done() or not self.look_ahead.result()
                or self.slowdowns >= self.config.replan_attempts):
            return
        self.slowdowns += 1
        sample = self.approach.samples(row - self.approach_row, row - self.approach_row + 1)
        start = PoseSample(*(np.array(figure[0]) for figure in (
            sample.position_m, sample.orientation, sample.velocity_m_s, sample.angular_velocity_rad_s,
            sample.acceleration_m_s2, sample.angular_acceleration_rad_s2)))
        aim = aim_schedule(self.robot, self.attached, np.concatenate([start.position_m, normalised(start.orientation)]),
                           self.safe_point_m, self.safe_orientation, self.config.approach_gains.aim_samples)
        margin_n = self.margin_within(aim.least_margin_n)
        # the first try whose margin this lowers is pulled as fast as the one before
        self.lowered = self.lowered or margin_n < self.margin_n
        self.margin_n = min(self.margin_n, margin_n)
        base = self.config.approach_gains
        self.gains = dataclasses.replace(base, position_frequency_rad_s=base.position_frequency_rad_s
                                         / self.config.replan_slowdown ** (self.slowdowns - self.lowered))
        self.approach, self.approach_row = self.steered(start, self.gains, self.margin_n, aim), row
        self.notes.append(f'the steered approach would turn the platform more than approach_turn_limit_deg or not '
                          f'arrive within approach_limit_s: steered again from tick {self.first_tick + row}, the '
                          f'position pulled at {self.gains.position_frequency_rad_s:.3g} rad/s, the tensions '
                          f'{self.margin_n:.3g} N above tension_min_n')
        self.look_ahead = self.planner.submit(self.fails, start, self.gains, self.margin_n, row, aim, urgent=True)

    def tabulate_to(self, row: int) -> None:
        """Step and tabulate the approach until row `row` is planned or the platform has
        arrived; RecoveryInfeasible where it turns too far or takes too long."""
        while self.arrival_row is None and self.tabulated_rows() <= row:
            start = self.tabulated_rows()
            if start >= self.row_limit:
                raise RecoveryInfeasible(
                    f'the steered approach did not bring the platform to its safe pose within '
                    f'{self.config.approach_limit_s:g} s')
            self.slow_down(start)
            sample = self.approach.samples(start - self.approach_row, start - self.approach_row + ROWS_PER_STEP)
            self.check(start, sample)
            dynamics = inverse_dynamics(self.robot, self.distribution, *sample.motion, attached=self.attached)
            self.tables.append(table_of(self.period_s, sample, dynamics))
            if start == 0 and not self.eased:
                self.eased = True
                ease_in(self.tables[0], self.command_nm, self.config.command_step_share, self.attached,
                        self.robot.motor.drum_radius_m)
            self.bounded_table(self.tables[-1])

    def check(self, start: int, sample: PoseSample) -> None:
        """Note an arrival among the rows of `sample` (the first is row `start`);
        RecoveryInfeasible where the platform turned too far."""
        angle_rad = self.approach.errors(sample)[1]
        if angle_rad.max() > self.turn_limit_rad:
            raise RecoveryInfeasible(
                f'the steered approach turns the platform {math.degrees(angle_rad.max()):.0f} deg from its safe '
                f'orientation, more than approach_turn_limit_deg ({self.config.approach_turn_limit_deg:g} deg) '
                f'beyond where it was')
        arrived = self.arrivals(self.approach, sample)
        if self.arrival_row is None and arrived.size:
            offset = int(arrived[0])
            self.arrival_row = start + offset
            zero = np.zeros(6)
            rest = inverse_dynamics(self.robot, self.distribution, sample.pose[offset], zero, zero,
                                    attached=self.attached)
            self.hold = JointReference(rest.joint_angle_rad, rest.joint_velocity_rad_s, rest.torque_nm)
            # the arrival is where the motors' pose is judged from (base.step)
            self.kinematics.expect(sample.position_m[offset], sample.orientation[offset])

    def reference_at(self, tick: int) -> JointReference | None:
        """The joint reference of `tick`: the approach's row; None after the arrival."""
        row = tick - self.first_tick
        self.tabulate_to(row)
        if self.arrival_row is not None and row > self.arrival_row:
            return None
        return table_reference(self.tables[row // ROWS_PER_STEP], row % ROWS_PER_STEP)

    def setpoint(self, tick: int, angle_rad, angular_velocity_rad_s):
        """(mode, None, JointReference) for tick + VERDICT_DELAY_TICKS: the approach's rows,
        then the arrival pose at rest from the tick SAFE_HOLD starts."""
        if self.mode == SAFE_HOLD:
            return self.mode, None, None
        due = tick + VERDICT_DELAY_TICKS
        reference = self.reference_at(due)
        if reference is None:
            self.mode = SAFE_HOLD
            self.phase_ticks[SAFE_HOLD] = due
            reference = self.hold
        return self.mode, None, reference

    def planned_references(self, tick: int, count: int, due_tick: int | None = None) -> list[tuple[int, JointReference]]:
        """(tick, joint reference) of the `count` ticks after tick + VERDICT_DELAY_TICKS (up
        to the arrival; none outside RECOVERY_MOVE)."""
        if self.mode != RECOVERY_MOVE:
            return []
        planned = []
        first = tick + VERDICT_DELAY_TICKS + 1
        for later in range(first, first + count):
            reference = self.reference_at(later)
            if reference is None:
                break
            planned.append((later, reference))
        return planned


def approach(naming: Naming, tracker, state) -> PoseApproach:
    """The steered approach from the platform's state on the naming tick and the pose
    tracker that found it (platform.named_state)."""
    recovery = PoseApproach(naming.robot, naming.config, naming.distribution, naming.period_s, naming.attached,
                            naming.tick, *state, naming.command_nm, naming.planner)
    recovery.tracker = tracker
    return recovery


class Steered(RecoveryStrategy):
    """A platform steered to its safe pose under tensions within their bounds (module
    docstring)."""

    name = 'steered'
    degrees_of_freedom = 6
    steers = True
    description = 'steered to its safe pose under tensions within their bounds'

    def prepare(self, robot: Robot, config) -> None:
        prepare_platform(robot, config)

    def start(self, naming: Naming) -> PoseApproach:
        return approach(naming, *named_state(naming))
