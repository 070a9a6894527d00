"""The joint-space reference of a Cartesian trajectory, tabulated at the control period."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .dynamics import inverse_dynamics
from .kinematics import inverse_kinematics
from .robot import Robot
from .tension_distribution import TensionDistribution
from .trajectories import Trajectory


@dataclass
class ReferenceTable:
    """Reference at t_k = k · period: pose (m), θ_d (rad), θ̇_d (rad/s), c_ID (N·m)."""

    period_s: float
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    feedforward_nm: np.ndarray

    def __len__(self) -> int:
        return self.position_m.shape[0]

    def index_at(self, time_s: float) -> int:
        """The sample at or before `time_s`, held at the ends."""
        return min(max(int(np.floor(time_s / self.period_s + 1e-9)), 0), len(self) - 1)


def tick_times(period_s: float, duration_s: float, start_s: float = 0.0) -> np.ndarray:
    """The times (s) of the ticks of `duration_s` from `start_s`, both ends included: where
    a trajectory is tabulated."""
    count = int(round(duration_s / period_s)) + 1
    return start_s + np.arange(count) * period_s


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
