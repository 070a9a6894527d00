"""A joint-space reference tabulated at the control period, of either body: a pose
trajectory (geometry.pose_trajectories; a point mass's has NO_TURN) sampled every period,
and its inverse dynamics (model.dynamics)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.geometry.pose_trajectories import PoseSample, PoseTrajectory
from cdpr_control.geometry.rotation import IDENTITY
from cdpr_control.model.dynamics import InverseDynamics, inverse_dynamics
from cdpr_control.tension_distribution import InfeasibleTensionError, TensionDistribution


@dataclass
class ReferenceTable:
    """Reference at t_k = k · period: position (m), velocity (m/s), θ_d (rad), θ̇_d (rad/s),
    c_ID (N·m); the orientation (unit quaternion) and angular velocity ω (rad/s, world
    frame) of a platform (rows of no entries for a point mass); the tensions the
    feed-forward plans (N)."""

    period_s: float
    position_m: np.ndarray
    velocity_m_s: np.ndarray
    angle_rad: np.ndarray
    angular_velocity_rad_s: np.ndarray
    feedforward_nm: np.ndarray
    orientation: np.ndarray
    platform_angular_velocity_rad_s: np.ndarray
    tension_n: np.ndarray

    def __len__(self) -> int:
        return self.position_m.shape[0]

    def orientation_at(self, row: int) -> np.ndarray:
        """The end-effector's orientation at `row`, as a pose message carries it (the
        identity for a point mass, which has none)."""
        return self.orientation[row] if self.orientation.shape[1] else IDENTITY

    def index_at(self, time_s: float) -> int:
        """The sample at or before `time_s`, held at the ends."""
        return min(max(int(np.floor(time_s / self.period_s + 1e-9)), 0), len(self) - 1)

    def rows(self, part: slice) -> 'ReferenceTable':
        """The table of the rows `part`."""
        return ReferenceTable(self.period_s, *(getattr(self, name)[part] for name in FIGURES))

    @classmethod
    def joined(cls, tables) -> 'ReferenceTable':
        """The rows of `tables` (of one period), one after the other."""
        return cls(tables[0].period_s, *(np.concatenate([getattr(table, name) for table in tables])
                                         for name in FIGURES))


# The figures of a ReferenceTable, a row per tick.
FIGURES = ('position_m', 'velocity_m_s', 'angle_rad', 'angular_velocity_rad_s', 'feedforward_nm', 'orientation',
           'platform_angular_velocity_rad_s', 'tension_n')


def tick_times(period_s: float, duration_s: float, start_s: float = 0.0) -> np.ndarray:
    """The times (s) of the ticks of `duration_s` from `start_s`, both ends included: where
    a trajectory is tabulated."""
    count = int(round(duration_s / period_s)) + 1
    return start_s + np.arange(count) * period_s


def sampled(trajectory: PoseTrajectory, period_s: float, rows: int | None = None, start_s: float = 0.0,
            duration_s: float | None = None) -> PoseSample:
    """The trajectory's samples every `period_s` from `start_s` for `duration_s` (to its end
    when None), its first `rows` where given."""
    times = tick_times(period_s, trajectory.duration_s - start_s if duration_s is None else duration_s, start_s)
    return trajectory.sample(times if rows is None else times[:rows])


def table_of(period_s: float, sample: PoseSample, dynamics: InverseDynamics, rows: slice = slice(None)) -> ReferenceTable:
    """The table of `sample`'s poses and the `rows` of their inverse dynamics."""
    return ReferenceTable(period_s, sample.position_m, sample.velocity_m_s, dynamics.joint_angle_rad[rows],
                          dynamics.joint_velocity_rad_s[rows], dynamics.torque_nm[rows], sample.orientation,
                          sample.angular_velocity_rad_s, dynamics.tension_n[rows])


def tabulate_reference(robot, distribution: TensionDistribution, trajectory: PoseTrajectory, period_s: float,
                       start_s: float = 0.0, duration_s: float | None = None, attached=None) -> ReferenceTable:
    """Sample `trajectory` every `period_s` from `start_s` (for `duration_s`; to its end when
    None) and compute IK and the feed-forward with the `attached` cables (all when None; a
    detached one's figures 0), every row at once; InfeasibleTensionError names the first
    pose no tensions hold."""
    sample = sampled(trajectory, period_s, start_s=start_s, duration_s=duration_s)
    return table_of(period_s, sample, inverse_dynamics(robot, distribution, *sample.motion, attached=attached))


def tabulate_references(robot, distribution: TensionDistribution, trajectories: list, period_s: float,
                        attached=None, rows: int | None = None) -> list:
    """`tabulate_reference` of each of `trajectories` (of its first `rows` rows where
    given), in one pass over all their rows (what each costs apart is mostly numpy's
    per-call time on tables of a few hundred rows); for a trajectory with a pose no
    tensions hold, in its place the InfeasibleTensionError naming the first."""
    samples = [sampled(trajectory, period_s, rows) for trajectory in trajectories]
    motion = [np.concatenate(figures) for figures in zip(*(sample.motion for sample in samples))]
    dynamics = inverse_dynamics(robot, distribution, *motion, attached=attached, nan_where_infeasible=True)
    tables, start = [], 0
    for sample in samples:
        part = slice(start, start + len(sample.position_m))
        start = part.stop
        missing = np.flatnonzero(np.isnan(dynamics.tension_n[part]).any(axis=-1))
        if missing.size:
            row = int(missing[0])
            tables.append(InfeasibleTensionError(
                f'no cable tensions above {distribution.tension_min_n:g} N pull the wrench',
                sample.position_m[row], row, sample.orientation[row] if sample.orientation.shape[1] else None))
            continue
        tables.append(table_of(period_s, sample, dynamics, part))
    return tables


class IncrementalTabulation:
    """`tabulate_reference` of a whole trajectory, a few rows per call, for a caller that
    must not stall (a realtime tick); the rows are those of one call."""

    def __init__(self, robot, distribution: TensionDistribution, trajectory: PoseTrajectory, period_s: float):
        self.robot = robot
        self.distribution = distribution
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
                self.robot, self.distribution, self.trajectory, self.period_s,
                start_s=self.rows_done * self.period_s, duration_s=(rows - 1) * self.period_s))
            self.rows_done += rows
        return self.rows_done >= self.count

    def table(self) -> ReferenceTable:
        """The whole table, once `advance` has returned True."""
        return ReferenceTable.joined(self.parts)
