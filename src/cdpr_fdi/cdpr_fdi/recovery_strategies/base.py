"""The interface of a recovery strategy (docs/recovery-strategies.md).

A `RecoveryStrategy` has a name (the value of recovery.strategy that chooses it), the
degrees of freedom of the end-effectors it recovers (`Robot.degrees_of_freedom`), what it
prepares when the supervisor is built (kernels to load, safe poses to find: the naming
tick has no time for them), and `start`, which the supervisor calls on the naming tick
with what it has then (`Naming`). The `StartedRecovery` it returns is stepped by the
supervisor on every tick after, until SAFE_HOLD or FAULT; the supervisor asks it nothing
else, and nothing of the kind of end-effector.

`config` below is the robot's cdpr_fdi.settings.config.RecoveryConfig, passed on as it is: that
module reads recovery.strategy against this package's strategies, so nothing here
imports it.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.control.controller import JointReference
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import TensionDistribution
from cdpr_msgs_py.contract import RECOVERY_MOVE, SAFE_HOLD, VERDICT_DELAY_TICKS


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


class StartedRecovery:
    """A recovery under way. Each has `safe_point_m` (where it takes the end-effector),
    `phase_ticks` (mode → the tick it began on), `timed_out` (whether a phase ended by its
    timeout rather than by its condition) and notes to say once."""

    safe_point_m: np.ndarray
    phase_ticks: dict[str, int]

    def __init__(self):
        self.timed_out = False
        self.notes: list[str] = []

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
        notes, self.notes = self.notes, []
        return notes

    def summary(self) -> dict:
        """What it adds to the supervisor's summary, in plain types (none by default)."""
        return {}


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
        for on the naming tick."""

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
