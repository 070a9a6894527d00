"""Statics of a platform: the tensions that hold it at a pose, and where such tensions
exist (the wrench-feasible workspace, for the platform's weight alone)."""
from __future__ import annotations

import numpy as np

from cdpr_control.platform.dynamics import motion_terms
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import InfeasibleTensionError, TensionDistribution, make_tension_distribution


def holding_terms(robot: Robot, positions_m, orientation) -> tuple[np.ndarray, np.ndarray]:
    """At each of the positions (n × 3, m) at one orientation: W (n × 6 × m) and the wrench
    −w_g (N, N·m) the cables must apply to hold the platform there at rest."""
    rows = len(positions_m)
    poses = np.concatenate([np.asarray(positions_m, dtype=float), np.broadcast_to(orientation, (rows, 4))], axis=1)
    terms = motion_terms(robot, poses, np.zeros((rows, 6)), np.zeros((rows, 6)))
    return terms.structure, terms.wrench_n


def holding_tensions(robot: Robot, distribution: TensionDistribution, position_m, orientation,
                     attached=None) -> np.ndarray:
    """τ (N, 0 for a detached cable) with W τ + w_g = 0 within the bounds;
    InfeasibleTensionError naming the pose where there are none."""
    attached = np.ones(robot.cable_count, dtype=bool) if attached is None else np.asarray(attached, dtype=bool)
    (structure,), (wrench,) = holding_terms(robot, np.atleast_2d(position_m), orientation)
    tension = np.zeros(robot.cable_count)
    try:
        tension[attached] = distribution.distribute(structure[:, attached], wrench)
    except InfeasibleTensionError as err:
        raise err.of_cables(np.flatnonzero(attached)).at(position_m, orientation) from None
    return tension


def wrench_feasible(robot: Robot, distribution: TensionDistribution, position_m, orientation,
                    attached=None) -> bool:
    """Whether tensions within the bounds hold the platform at rest at the pose."""
    try:
        holding_tensions(robot, distribution, position_m, orientation, attached)
    except InfeasibleTensionError:
        return False
    return True


def workspace_grid(robot: Robot, spacing_m: float) -> np.ndarray:
    """Points (n × 3) spaced about `spacing_m` apart over the workspace box, its faces included."""
    axes = [np.linspace(low, high, max(2, int(round((high - low) / spacing_m)) + 1))
            for low, high in zip(robot.workspace_min_m, robot.workspace_max_m)]
    return np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)


def wrench_feasible_share(robot: Robot, distribution: TensionDistribution, orientation, points,
                          attached=None) -> float:
    """The share of `points` where the platform, at `orientation`, can be held at rest."""
    return float(np.mean([wrench_feasible(robot, distribution, point, orientation, attached)
                          for point in points]))


def static_tensions(robot: Robot, position_m, orientation, attached=None) -> np.ndarray:
    """The tensions a plant holds the platform at rest with (before its first command,
    and as the elastic cables' stretch at its start): the minimum-norm ones within the
    cable bounds (the pseudo-inverse's wherever that is inside them)."""
    return holding_tensions(robot, static_distribution(robot), position_m, orientation, attached)


def static_distribution(robot: Robot) -> TensionDistribution:
    """How a plant shares a platform's weight at rest: the minimum-norm tensions within
    the cable bounds."""
    return make_tension_distribution('bounded_minimum_norm', robot.tension_min_n, robot.tension_max_n)


def static_tensions_each(robot: Robot, positions_m, orientation, attached=None) -> np.ndarray:
    """`static_tensions` at each of the positions (n × 3, m) at one orientation, every row
    at once; a row of NaN where no tensions within the bounds hold the platform."""
    attached = np.ones(robot.cable_count, dtype=bool) if attached is None else np.asarray(attached, dtype=bool)
    structures, wrenches = holding_terms(robot, positions_m, orientation)
    tension = np.zeros((len(wrenches), robot.cable_count))
    tension[:, attached] = static_distribution(robot).distribute_each(structures[:, :, attached], wrenches)
    return tension
