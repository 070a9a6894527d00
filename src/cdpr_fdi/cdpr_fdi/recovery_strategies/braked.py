"""A platform's recovery braked where it is named, recovery.strategy `braked` (issue 29;
docs/platform.md).

Where the remaining cables can hold the platform at rest where it is at the naming —
static tensions within [τ_min, τ_max] exist at its pose — position control takes over at
once (RECOVERY_MOVE), in two parts planned one after the other:

- the brake, planned at the naming: quintics from the platform's twist bring its
  position and its orientation to rest (BrakedTurn: a plan that took the orientation as
  still would step the motors' speeds, and the platform turns fast in the ticks after a
  break), the path starting with `brake_lift_m_s2` upward (every cable then pulls more
  than at rest, a margin for the ticks in which the drives take over), its first tick
  going `command_step_share` of the way from the torques commanded at the naming
  (ease_in). The first `committed_brake_s` of one try is planned and sent at once — the
  brake as configured where the cables left hold the platform at its rest, else the
  try whose rest they hold best, else the shortest (try_to_commit) —; the rest of the
  way towards every try's rest from where that ends, by the planner (below) — a
  realtime supervisor's drives take over within a tick or two, not once every try is
  planned; should the tries come later than the drives need them, the committed try's
  rest of the way is kept, so that what the drives do hangs little on the planner's
  speed (docs/platform.md);
- the move, planned from the brake's rest by the `planner` (planning.py: at once, or on
  a thread while a realtime loop brakes): a straight quintic takes the position to the
  safe pose's while the orientation turns about a fixed axis with the same law; tried as
  configured, then slower and slower. Should its plan not be ready when the brake ends,
  the platform is held at rest where the brake left it until it is; then SAFE_HOLD.

Each part is tabulated per tick for the remaining cables, their tensions planned
`plan_tension_margin_n` above τ_min: the first try that keeps that margin is taken.
Where no try does (named near the border), the margin is lowered where a pose needs it
(cdpr_control.tension_distribution.LoweredFloor: the wrench pulled exactly, the least
tension as high as the pose allows, not below τ_min) and the try with the highest least
tension is taken. Where no try keeps every cable at τ_min, the last (the shortest brake,
the slowest move) is tabulated with the floored least-squares tensions on those rows
(FlooredLeastSquares): the wrench out of reach is missed by a little, and the joints'
position control keeps the platform on its way. What each part gave up is said once
(`take_notes`).

Where no static tensions within the bounds hold the platform at its pose it cannot be
braked to rest there: it is steered to its safe pose instead (steered.py).
"""
from __future__ import annotations

import dataclasses
import math
from concurrent.futures import Future

import numpy as np

from cdpr_control.control.controller import JointReference
from cdpr_control.model.reference_table import ReferenceTable, tabulate_reference, tabulate_references
from cdpr_control.geometry.pose_trajectories import BrakedTurn, PoseSample, PoseTrajectory, Turn
from cdpr_control.model.robot import Robot
from cdpr_control.geometry.rotation import difference, from_rotation_vector, normalised, product
from cdpr_control.platform.safe_pose import tension_margin_n
from cdpr_control.tension_distribution import FlooredLeastSquares, InfeasibleTensionError, TensionDistribution
from cdpr_control.tension_distribution.base import BOUND_TOLERANCE_N
from cdpr_control.geometry.trajectories import HermiteQuintic, Hold, Sequence
from cdpr_msgs_py.contract import RECOVERY_MOVE, SAFE_HOLD, VERDICT_DELAY_TICKS

from ..recovery_planning.planning import PlanAtOnce
from .base import Naming, RecoveryStrategy, StartedRecovery, table_reference
from .platform import PlatformRecovery, after_the_naming_tick, ease_in, named_state, prepare_platform
from .steered import approach

# Least tensions (N) of two tries this close count as equal (best_of says which is kept).
LEAST_TENSION_RESOLUTION_N = 0.01


def brake_from(state: PoseSample, duration_s: float, rest_m, rest_orientation) -> PoseTrajectory:
    """A brake from `state` (its acceleration and angular acceleration taken over) to rest
    at (`rest_m`, `rest_orientation`) over `duration_s`, the orientation about ω's axis
    (BrakedTurn)."""
    path = HermiteQuintic(state.position_m, state.velocity_m_s, rest_m, np.zeros(3), duration_s,
                          state.acceleration_m_s2)
    return PoseTrajectory(path, BrakedTurn(state.orientation, state.angular_velocity_rad_s, duration_s,
                                           state.angular_acceleration_rad_s2,
                                           difference(rest_orientation, state.orientation)))


class PoseRecovery(PlatformRecovery):
    """Steps through a platform's braked recovery, one control tick at a time, as
    paper.Recovery does a point mass's: `setpoint(tick, angle, speed)` gives the mode and
    the joint reference of the next tick."""

    def __init__(self, robot: Robot, config, distribution: TensionDistribution,
                 period_s: float, attached: np.ndarray, start_tick: int, position_m, orientation,
                 velocity_m_s, angular_velocity_rad_s, command_nm, planner=None):
        """From the pose (p, q) and twist (v m/s, ω rad/s) the remaining (`attached`) cables
        give at detection, and the torques (N·m) the motors were commanded on that tick, to
        their safe pose (recovery.safe_pose_for), the move planned by `planner`
        (planning.py; at once when None); static tensions within the bounds hold the
        platform at that pose (else steered.py); RecoveryInfeasible where there is
        no safe pose."""
        super().__init__(robot, config, distribution, period_s, attached, start_tick)
        self.planner = planner or PlanAtOnce()
        command_nm = np.asarray(command_nm, dtype=float)
        self.brake, self.continuation = self.plan_brake(after_the_naming_tick(
            robot, self.attached, np.asarray(position_m, dtype=float), normalised(orientation),
            np.asarray(velocity_m_s, dtype=float), np.asarray(angular_velocity_rad_s, dtype=float), command_nm,
            period_s))
        ease_in(self.brake, command_nm, config.command_step_share, self.attached, robot.motor.drum_radius_m)
        self.bounded_table(self.brake)
        # the brake's last row (its rest, where the move starts), once the brake is settled
        self.brake_end_tick: int | None = None
        self.planned_move = None
        self.move: ReferenceTable | None = None
        self.move_start_tick: int | None = None
        self.settle_brake(self.first_tick)

    def plan_brake(self, start: PoseSample):
        """The brake's joint references per tick from `start` (the state on the tick after
        the naming; module docstring), its last row at rest:
        over brake_s(|v|), then over that shortened `replan_slowdown` times, up to
        `replan_attempts` times; each a whole number of periods. The first
        `committed_brake_s` of one of them (try_to_commit) at once, so the drives take
        over within a tick or two, and the rest of every try from where they end handed to
        the planner (a Future: `continue_brake`); every try at once where there is no time to commit
        (`committed_brake_s` 0, or as long as the shortest brake) or the committed rows
        are held by no tensions."""
        config = self.config
        velocity_m_s, angular_velocity_rad_s = start.velocity_m_s, start.angular_velocity_rad_s
        brake_s = config.brake_s(float(np.linalg.norm(velocity_m_s)))
        gravity = np.linalg.norm(self.robot.gravity_m_s2)
        up = -self.robot.gravity_m_s2 / gravity if gravity > 0.0 else np.zeros(3)
        naming = dataclasses.replace(start, acceleration_m_s2=config.brake_lift_m_s2 * up)
        rests = []
        for attempt in range(config.replan_attempts + 1):
            duration_s = math.ceil(brake_s / config.replan_slowdown ** attempt / self.period_s) * self.period_s
            # a braked motion goes on by half its speed times the brake's time
            rests.append((duration_s, start.position_m + 0.5 * duration_s * velocity_m_s,
                          product(from_rotation_vector(0.5 * duration_s * angular_velocity_rad_s), naming.orientation)))
        tries = [brake_from(naming, *rest) for rest in rests]
        committed = round(config.committed_brake_s / self.period_s)
        if 0 < committed < round(rests[-1][0] / self.period_s) - 1:
            self.committed_try = self.try_to_commit(rests)
            first = tries[self.committed_try]
            prefix = tabulate_references(self.robot, self.lowered, [first], self.period_s, self.attached,
                                              rows=committed + 1)[0]
            if not isinstance(prefix, InfeasibleTensionError):
                self.committed_ticks = committed
                elapsed_s = committed * self.period_s
                committed_end = first.sample(elapsed_s)
                self.rest_tries = [brake_from(committed_end, duration_s - elapsed_s, position, orientation)
                                   for duration_s, position, orientation in rests]
                self.first_rest = Future()
                return prefix, self.planner.submit(self.continue_brake, self.rest_tries, self.committed_try,
                                                   self.first_rest, urgent=True)
        table, note = self.best_of(tries, 'the brake')
        self.notes += [note] if note else []
        return table, None

    def try_to_commit(self, rests) -> int:
        """Of the brake's tries ((duration s, rest position, rest orientation) each), the one
        whose first rows are sent at the naming and whose rest of the way is kept should
        the others come too late: the first, where the cables left hold the platform at
        its rest; else the one whose rest they hold with the largest static tension
        margin; where they hold none, the shortest, which best_of would then plan with
        the floored tensions."""
        margins = [tension_margin_n(self.robot, position, orientation, self.attached)
                   for _, position, orientation in rests]
        if margins[0] > 0.0:
            return 0
        return int(np.argmax(margins)) if max(margins) > 0.0 else len(rests) - 1

    @property
    def switch_tick(self) -> int:
        """The first tick of the brake's rows planned after the naming."""
        return self.first_tick + self.committed_ticks

    def continue_brake(self, tries: list[PoseTrajectory], committed_try: int, first_rest: Future):
        """The brake's rows from its committed first ones on (the `tries`: from where those
        end, the committed try's, towards each try's rest over what is left of its time;
        the committed try's own rest of the way among them, so the tries and the choice
        are the module docstring's), and a note. The committed try's table is tabulated
        first and goes to `first_rest` at once: the brake to keep should the others come
        too late."""
        return self.best_of(tries, 'the brake', tables=self.tabulated_tries(tries, first_rest, committed_try))

    def settle_brake(self, needed_tick: int, due_tick: int | None = None) -> None:
        """Once the brake's rows after its committed ones are planned, they follow those.
        Where a reference of the tick `needed_tick` or later is wanted first (rows sent out
        cannot be taken back): the tries are waited for until the drives are about to
        need those rows (`due_tick`, the first tick whose row may be wanted before the
        next call; `needed_tick` where not given), then the committed try's rest of the
        way is kept, as tabulated beside them, or planned here and now (a few ms, the
        drives still on the committed rows sent ahead) where it is not ready; the note
        says so.
        Then the move is handed to the planner, from the brake's rest."""
        if self.continuation is not None:
            if self.continuation.done():
                rest, note = self.continuation.result()
            elif needed_tick >= self.switch_tick:
                kept = self.rest_tries[self.committed_try:self.committed_try + 1]
                if self.first_rest.done():
                    if (needed_tick if due_tick is None else due_tick) < self.switch_tick:
                        return
                    tables = iter([self.first_rest.result()])
                else:
                    tables = self.tabulated_tries(kept)
                rest, note = self.best_of(kept, 'the brake', tables=tables)
                note = (f'the brake\'s tries were not planned by tick {self.switch_tick}: braked as first planned'
                        + (f'; {note}' if note else ''))
            else:
                return
            self.continuation = None
            committed = self.committed_ticks
            self.brake = ReferenceTable.joined([self.brake.rows(slice(committed)), rest])
            if not note and not self.keeps_margin(self.brake):
                note = (f'the brake cannot keep the planned tension margin in its first {committed} ticks, '
                        f'planned at once: the least tension {self.brake.tension_n[:, self.attached].min():.2f} N')
            self.notes += [note] if note else []
        if self.planned_move is None:
            self.brake_end_tick = self.first_tick + len(self.brake) - 1
            self.planned_move = self.planner.submit(self.plan_move, self.brake.position_m[-1],
                                                    self.brake.orientation[-1])

    def keeps_margin(self, table) -> bool:
        """Whether a table's tensions all keep the planned margin (False for an error)."""
        return (not isinstance(table, InfeasibleTensionError)
                and table.tension_n[:, self.attached].min() >= self.margin.tension_min_n - BOUND_TOLERANCE_N)

    def plan_move(self, position_m, orientation) -> tuple[ReferenceTable, str]:
        """The move's joint references per tick from rest at (p, q) to the safe pose, its
        last row there at rest, and a note where it cannot keep the margin: over
        move_s(distance), then `replan_slowdown` times longer, up to `replan_attempts`
        times."""
        config = self.config
        move_s = config.move_s(float(np.linalg.norm(self.safe_point_m - position_m)))
        moves = []
        for attempt in range(config.replan_attempts + 1):
            duration_s = move_s * config.replan_slowdown ** attempt
            path = Sequence([HermiteQuintic(position_m, np.zeros(3), self.safe_point_m, np.zeros(3), duration_s),
                             Hold(self.safe_point_m, self.period_s)])
            moves.append(PoseTrajectory(path, Turn.between(orientation, self.safe_orientation, duration_s)))
        return self.best_of(moves, 'the move to the safe pose', slowest_on_ties=True)

    def best_of(self, tries: list[PoseTrajectory], part: str, slowest_on_ties: bool = False,
                tables=None) -> tuple[ReferenceTable, str]:
        """The table of the first try whose tensions keep the planned margin; else of the
        try whose least tension is highest with the margin lowered where a pose needs it
        (of equals, the first, or with `slowest_on_ties` the last); else of the last try
        with the floored least-squares tensions; with a note saying which where it is not
        the first kind ('' where it is). The tries' `tables` (tabulated_tries', where not
        given) are taken one by one, as far as needed."""
        floor = self.margin.tension_min_n - BOUND_TOLERANCE_N
        best, best_least, short = None, -np.inf, ''
        for table in self.tabulated_tries(tries) if tables is None else tables:
            if isinstance(table, InfeasibleTensionError):
                short = short or str(table)
                continue
            least = table.tension_n[:, self.attached].min(axis=1)
            if least.min() >= floor:
                return self.bounded_table(table), ''
            if not short:
                where = table.position_m[int(np.argmax(least < floor))]
                short = (f'{self.margin.tension_min_n:g} N not kept from p = '
                         f'({", ".join(f"{value:.4f}" for value in where)}) m')
            if least.min() > best_least + LEAST_TENSION_RESOLUTION_N or (
                    slowest_on_ties and least.min() > best_least - LEAST_TENSION_RESOLUTION_N):
                best, best_least = table, float(least.min())
        if best is not None:
            return self.bounded_table(best), (
                f'{part} cannot keep the planned tension margin ({short}): planned with the margin each pose '
                f'allows, the least tension {best_least:.2f} N')
        return (self.bounded_table(tabulate_reference(self.robot, FlooredLeastSquares(self.lowered), tries[-1],
                                                      self.period_s, attached=self.attached)),
                f'{part} cannot keep the planned tension margin ({short}); no try keeps every cable at '
                f'{self.robot.tension_min_n:g} N: the last planned nearest the bounds')

    def tabulated_tries(self, tries: list[PoseTrajectory], first_table: Future | None = None, first: int = 0):
        """Each try's table with the lowered floor (or the error naming where not even
        τ_min holds), in the tries' order: tries[`first`] tabulated alone (and handed to
        `first_table`), then the others in one pass — where the first try is it, only if
        it does not keep the margin."""
        alone = tabulate_references(self.robot, self.lowered, tries[first:first + 1], self.period_s,
                                         self.attached)[0]
        if first_table is not None:
            first_table.set_result(alone)
        if first == 0:
            yield alone
        others = tries[:first] + tries[first + 1:]
        if others:
            tables = tabulate_references(self.robot, self.lowered, others, self.period_s, self.attached)
            yield from tables[:first] + ([alone] if first else []) + tables[first:]

    def replan(self, tick: int, angle_rad, angular_velocity_rad_s) -> None:
        """The move to the safe pose planned again from where the motors say the platform
        is, from the tick the verdict on `tick` is due, at once (StartedRecovery.replan):
        the drives hold the last reference meanwhile, the platform at rest."""
        position, orientation = self.pose(angle_rad)
        self.move, note = self.plan_move(np.asarray(position, dtype=float), normalised(orientation))
        self.move_start_tick = tick + VERDICT_DELAY_TICKS
        self.notes += [note] if note else []
        self.mode = RECOVERY_MOVE

    def take_move(self, tick: int) -> None:
        """The move, once planned: its first row (the brake's rest) on the brake's last
        tick, or on the tick the verdict on `tick` is due where the plan came later (the
        platform held at rest till then). Raises what planning raised."""
        if self.move is not None or self.planned_move is None or not self.planned_move.done():
            return
        self.move, note = self.planned_move.result()
        self.move_start_tick = max(self.brake_end_tick, tick + VERDICT_DELAY_TICKS)
        self.notes += [note] if note else []
        if self.move_start_tick > self.brake_end_tick:
            self.notes.append(f'the move to the safe pose was planned {self.move_start_tick - self.brake_end_tick} '
                              f'ticks after the brake ended: the platform held at rest meanwhile')

    def reference_at(self, tick: int) -> JointReference | None:
        """The joint reference of `tick` as far as the plans fix it: a brake's row; its
        rest until the move starts (None ahead of now: the move may start sooner); a
        move's row; None after the move."""
        if self.move is not None and tick >= self.move_start_tick:
            row = tick - self.move_start_tick
            return table_reference(self.move, row) if row < len(self.move) else None
        row = tick - self.first_tick
        return table_reference(self.brake, min(row, len(self.brake) - 1))

    def setpoint(self, tick: int, angle_rad, angular_velocity_rad_s):
        """(mode, None, JointReference or None) for tick + VERDICT_DELAY_TICKS: the brake's
        rows, its rest until the move is planned, the move's rows, the last on the tick
        SAFE_HOLD starts, then nothing (the controller holds it at rest)."""
        if self.mode == SAFE_HOLD:
            return self.mode, None, None
        due = tick + VERDICT_DELAY_TICKS
        self.settle_brake(due)
        self.take_move(tick)
        reference = self.reference_at(due)
        if reference is None:
            self.mode = SAFE_HOLD
            self.phase_ticks[SAFE_HOLD] = due
            reference = table_reference(self.move, len(self.move) - 1)
        return self.mode, None, reference

    def planned_references(self, tick: int, count: int, due_tick: int | None = None) -> list[tuple[int, JointReference]]:
        """(tick, joint reference) of the `count` ticks after tick + VERDICT_DELAY_TICKS that
        the plans already fix (the brake's rows up to its rest — settled first, as they are to be
        sent, by `due_tick` (settle_brake) —; the move's once taken); none outside
        RECOVERY_MOVE."""
        if self.mode != RECOVERY_MOVE:
            return []
        self.settle_brake(tick + VERDICT_DELAY_TICKS + count, due_tick)
        self.take_move(tick)
        # the brake's rows as far as they are settled, and its rest until the move is taken
        last = (self.switch_tick - 1 if self.continuation is not None
                else self.brake_end_tick if self.move is None else None)
        planned = []
        first = tick + VERDICT_DELAY_TICKS + 1
        for later in range(first, first + count):
            if last is not None and later > last:
                break
            reference = self.reference_at(later)
            if reference is None:
                break
            planned.append((later, reference))
        return planned


class Braked(RecoveryStrategy):
    """A platform braked to rest where it is named and moved to its safe pose, where the
    cables left hold it at rest there; steered there elsewhere (module docstring)."""

    name = 'braked'
    degrees_of_freedom = 6
    # steered where the cables left cannot hold the platform at rest
    steers = True
    description = 'braked and moved to its safe pose where the cables left hold it at rest, else steered there'

    def prepare(self, robot: Robot, config) -> None:
        prepare_platform(robot, config)

    def start(self, naming: Naming) -> StartedRecovery:
        tracker, state = named_state(naming)
        position, orientation, velocity, angular_velocity = state
        if tension_margin_n(naming.robot, position, orientation, naming.attached) < 0.0:
            return approach(naming, tracker, state)
        recovery = PoseRecovery(naming.robot, naming.config, naming.distribution, naming.period_s, naming.attached,
                                naming.tick, position, orientation, velocity, angular_velocity, naming.command_nm,
                                naming.planner)
        recovery.tracker = tracker
        return recovery
