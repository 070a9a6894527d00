"""The joint-space reference of a Cartesian trajectory, tabulated at the control period."""
from __future__ import annotations

import numpy as np

from cdpr_control.point_mass.dynamics import inverse_dynamics
from cdpr_control.point_mass.kinematics import inverse_kinematics
from cdpr_control.model.reference_table import ReferenceTable, tick_times
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import TensionDistribution
from cdpr_control.geometry.trajectories import Trajectory


def tabulate_reference(robot: Robot, tension_distribution: TensionDistribution,
                       trajectory: Trajectory, period_s: float, start_s: float = 0.0,
                       duration_s: float | None = None, attached=None) -> ReferenceTable:
    """Sample `trajectory` from `start_s` every `period_s` and compute IK and the feed-forward.

    With `attached` (boolean mask) only those cables carry the load; the others' rows are 0.
    """
    duration_s = trajectory.duration_s - start_s if duration_s is None else duration_s
    position, velocity, acceleration = trajectory.sample(tick_times(period_s, duration_s, start_s))
    dynamics = inverse_dynamics(robot, tension_distribution, position, velocity, acceleration,
                                attached)
    angle = inverse_kinematics(robot, position)
    if attached is not None:
        angle[:, ~attached] = 0.0
    return ReferenceTable(period_s, position, velocity, angle, dynamics.joint_velocity_rad_s,
                          dynamics.torque_nm)


class IncrementalTabulation:
    """`tabulate_reference` of a whole trajectory, a few rows per call, for a caller that
    must not stall (a realtime tick); the rows are those of one call."""

    def __init__(self, robot: Robot, tension_distribution: TensionDistribution,
                 trajectory: Trajectory, period_s: float):
        self.robot = robot
        self.tension_distribution = tension_distribution
        self.trajectory = trajectory
        self.period_s = period_s
        self.count = int(round(trajectory.duration_s / period_s)) + 1
        self.parts: list[ReferenceTable] = []
        self.rows_done = 0

    def advance(self, rows: int) -> bool:
        """Tabulate up to `rows` more rows; True when every row is done. Raises what
        tabulate_reference raises (InfeasibleTensionError) for the rows it reaches."""
        rows = min(rows, self.count - self.rows_done)
        if rows > 0:
            self.parts.append(tabulate_reference(
                self.robot, self.tension_distribution, self.trajectory, self.period_s,
                start_s=self.rows_done * self.period_s, duration_s=(rows - 1) * self.period_s))
            self.rows_done += rows
        return self.rows_done >= self.count

    def table(self) -> ReferenceTable:
        """The whole table, once `advance` has returned True."""
        return ReferenceTable(self.period_s, *(
            np.concatenate([getattr(part, name) for part in self.parts])
            for name in ('position_m', 'velocity_m_s', 'angle_rad', 'angular_velocity_rad_s',
                         'feedforward_nm')))
