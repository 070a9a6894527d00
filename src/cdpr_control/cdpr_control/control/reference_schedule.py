"""The reference of every tick: a first table from tick 0, then each goal's move spliced
on where the motion before it comes to rest.

A goal is reached by a straight quintic move at the goal peak speed, followed by one
period of rest at the goal; the goals wait in a queue and each move starts where the
previous planned one ends. Planning a move may be spread over calls (a realtime tick
must not stall); a move is adopted once every row is tabulated, after the last planned
segment ends and never before the first tick whose reference is not yet out.
"""
from __future__ import annotations

from collections import deque
from dataclasses import dataclass

import numpy as np

from cdpr_control.model.reference_table import IncrementalTabulation, ReferenceTable
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import InfeasibleTensionError, TensionDistribution
from cdpr_control.geometry.pose_trajectories import PoseTrajectory
from cdpr_control.geometry.trajectories import Hold, Sequence, StraightLine


class GoalRejected(ValueError):
    """A goal that gets no move; the message says why."""


@dataclass(frozen=True)
class PlannedMove:
    """A goal's move, adopted: it starts at `start_tick` and lasts `duration_s`."""

    goal_m: np.ndarray
    start_tick: int
    duration_s: float


class ReferenceSchedule:

    def __init__(self, robot: Robot, tension_distribution: TensionDistribution, period_s: float,
                 goal_peak_speed_m_s: float, first: ReferenceTable):
        self.robot = robot
        self.tension_distribution = tension_distribution
        self.period_s = period_s
        self.goal_peak_speed_m_s = goal_peak_speed_m_s
        # (first tick, table), by first tick; each holds its last row until the next begins
        self.segments: list[tuple[int, ReferenceTable]] = [(0, first)]
        self.goals: deque[np.ndarray] = deque()   # accepted, waiting to be planned, in order
        self.planning: tuple[np.ndarray, IncrementalTabulation] | None = None
        self.next_tick = 0   # the first tick whose reference is not yet out

    def add_goal(self, goal_m) -> None:
        """Queue a goal (m); raises GoalRejected for one outside the workspace (or not
        a number)."""
        goal = np.asarray(goal_m, dtype=float)
        try:
            self.robot.body.check_goal(goal)
        except ValueError as err:
            raise GoalRejected(str(err)) from None
        if not np.all((goal >= self.robot.workspace_min_m) & (goal <= self.robot.workspace_max_m)):
            raise GoalRejected(f'goal {goal} outside the workspace')
        self.goals.append(goal)

    def plan(self, rows: int | None = None) -> list[PlannedMove | GoalRejected]:
        """Go on planning the waiting goals in order, `rows` more rows of the move under
        way (None: every row), then the next goal's; what became of each goal settled
        meanwhile: adopted, or rejected because its tensions are infeasible."""
        settled: list[PlannedMove | GoalRejected] = []
        while True:
            if self.planning is not None:
                goal, tabulation = self.planning
                try:
                    if not tabulation.advance(tabulation.count if rows is None else rows):
                        return settled
                    settled.append(self._adopt(goal, tabulation.table()))
                except InfeasibleTensionError as err:
                    settled.append(GoalRejected(f'goal {goal} cannot be reached: {err}'))
                self.planning = None
            if not self.goals:
                return settled
            goal = self.goals.popleft()
            here = self.end_m
            if not np.allclose(goal, here):
                trajectory = PoseTrajectory(Sequence([
                    StraightLine.with_peak_speed(here, goal, self.goal_peak_speed_m_s), Hold(goal, self.period_s)]))
                self.planning = (goal, IncrementalTabulation(self.robot, self.tension_distribution,
                                                             trajectory, self.period_s))

    @property
    def end_m(self) -> np.ndarray:
        """Where the planned motion comes to rest (m)."""
        return self.segments[-1][1].position_m[-1]

    def _adopt(self, goal: np.ndarray, table: ReferenceTable) -> PlannedMove:
        start, last = self.segments[-1]
        begin = max(start + len(last), self.next_tick)
        self.segments.append((begin, table))
        # Segments wholly out are done with: a long run of goals must not pile them up.
        self.segments = [segment for segment in self.segments[:-1]
                         if segment[0] + len(segment[1]) > self.next_tick] + self.segments[-1:]
        return PlannedMove(goal, begin, len(table) * self.period_s)

    def due(self, tick: int, lead: int) -> range:
        """The ticks whose references go out at `tick`, `lead` ahead, each once; they count
        as out from now. After a jump in time the ticks jumped over are of no use."""
        first = max(self.next_tick, tick)
        self.next_tick = max(first, tick + lead + 1)
        return range(first, tick + lead + 1)

    def sample(self, tick: int) -> tuple[ReferenceTable, int]:
        """The table and row of `tick`'s reference."""
        start, table = next((s, t) for s, t in reversed(self.segments) if s <= tick)
        return table, min(tick - start, len(table) - 1)
