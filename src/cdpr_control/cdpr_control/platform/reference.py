"""The joint-space reference of a platform's motion, tabulated at the control period."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cdpr_control.platform import dynamics as pose_dynamics
from cdpr_control.geometry.pose_trajectories import PoseTrajectory
from cdpr_control.model.reference_table import ReferenceTable, tick_times
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import InfeasibleTensionError, TensionDistribution


@dataclass
class PoseReferenceTable(ReferenceTable):
    """A platform's reference (ReferenceTable's rows, θ̇_d its angular_velocity_rad_s), and
    per tick its orientation (unit quaternion), its angular velocity ω (rad/s, world
    frame) and the tensions the feed-forward plans (N)."""

    orientation: np.ndarray
    platform_angular_velocity_rad_s: np.ndarray
    tension_n: np.ndarray

    def orientation_at(self, row: int) -> np.ndarray:
        return self.orientation[row]


def tabulate_pose_reference(robot: Robot, tension_distribution: TensionDistribution,
                            trajectory: PoseTrajectory, period_s: float, attached=None) -> PoseReferenceTable:
    """Sample `trajectory` every `period_s` from its start to its end and compute IK and the
    feed-forward with the `attached` cables (all when None; a detached one's figures 0),
    every row at once; InfeasibleTensionError names the first pose no tensions hold."""
    sample = sampled(trajectory, period_s)
    dynamics = pose_dynamics.inverse_dynamics(robot, tension_distribution, *sample.motion, attached=attached)
    return table_of(period_s, sample, dynamics, slice(None))


def sampled(trajectory: PoseTrajectory, period_s: float, rows: int | None = None):
    """The trajectory's PoseSample every `period_s` from its start to its end (its first
    `rows` samples where given)."""
    times = tick_times(period_s, trajectory.duration_s)
    return trajectory.sample(times if rows is None else times[:rows])


def table_of(period_s: float, sample, dynamics, rows: slice) -> PoseReferenceTable:
    """The table of `sample`'s poses and the `rows` of their inverse dynamics."""
    return PoseReferenceTable(period_s, sample.position_m, sample.velocity_m_s, dynamics.joint_angle_rad[rows],
                              dynamics.joint_velocity_rad_s[rows], dynamics.torque_nm[rows], sample.orientation,
                              sample.angular_velocity_rad_s, dynamics.tension_n[rows])


def tabulate_pose_references(robot: Robot, tension_distribution: TensionDistribution, trajectories: list,
                             period_s: float, attached=None, rows: int | None = None) -> list:
    """`tabulate_pose_reference` of each of `trajectories` (of its first `rows` rows where
    given), in one pass over all their rows (what each costs apart is mostly numpy's
    per-call time on tables of a few hundred rows); for a trajectory with a pose no
    tensions hold, in its place the InfeasibleTensionError naming the first."""
    samples = [sampled(trajectory, period_s, rows) for trajectory in trajectories]
    motion = [np.concatenate(figures) for figures in zip(*(sample.motion for sample in samples))]
    dynamics = pose_dynamics.inverse_dynamics(robot, tension_distribution, *motion, attached=attached,
                                              nan_where_infeasible=True)
    tables, start = [], 0
    for sample in samples:
        part = slice(start, start + len(sample.position_m))
        start = part.stop
        missing = np.flatnonzero(np.isnan(dynamics.tension_n[part]).any(axis=-1))
        if missing.size:
            tables.append(InfeasibleTensionError(
                f'no cable tensions above {tension_distribution.tension_min_n:g} N pull the wrench',
                sample.position_m[missing[0]], int(missing[0]), sample.orientation[missing[0]]))
            continue
        tables.append(table_of(period_s, sample, dynamics, part))
    return tables
