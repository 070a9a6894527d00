"""Static equilibrium of the end-effector under gravity with a set of cables."""
from __future__ import annotations

from itertools import combinations

import numpy as np

from cdpr_control.point_mass.kinematics import cable_vectors
from cdpr_control.model.robot import Robot
from cdpr_control.tension_distribution import (BoundedMinimumNorm, InfeasibleTensionError, PseudoInverse,
                                   minimum_norm)

SINGULAR_TOLERANCE = 1e-12


def static_tensions(robot: Robot, position_m, attached) -> np.ndarray:
    """t = S_R⁺ (−m_e g) (paper eq. 22): tensions (N) holding the end-effector still.

    Entries of detached cables are 0. Negative entries mean the pose is outside the
    static-equilibrium workspace of the attached cables.
    """
    u, _ = cable_vectors(robot.exit_points_m[attached], position_m)
    tensions = np.zeros(robot.cable_count)
    tensions[attached] = minimum_norm(u.T, -robot.weight_wrench_n)
    return tensions


def holding_torque_nm(robot: Robot, position_m, attached) -> np.ndarray:
    """c = −ρ t (N·m), t the static tensions of the `attached` cables at p: the motor
    torques that hold the end-effector still there (pulling is negative)."""
    return -robot.motor.drum_radius_m * static_tensions(robot, position_m, attached)


def in_static_equilibrium(robot: Robot, position_m, attached, tolerance: float = 1e-9) -> bool:
    """True when non-negative tensions of the `attached` cables balance gravity at p.

    −m_e g must lie in the cone spanned by the unit vectors u_i; by Carathéodory's
    theorem it does iff it lies in the cone of some 3 of them (or fewer, which a
    triple containing them also covers).
    """
    u, _ = cable_vectors(robot.exit_points_m[attached], position_m)
    load = -robot.weight_wrench_n
    for triple in combinations(range(u.shape[0]), 3):
        basis = u[list(triple)].T
        if abs(np.linalg.det(basis)) < SINGULAR_TOLERANCE:
            continue
        coefficients = np.linalg.solve(basis, load)
        if np.min(coefficients) >= -tolerance * np.linalg.norm(load):
            return True
    return _in_planar_cone(u, load, tolerance)


def _in_planar_cone(u: np.ndarray, load: np.ndarray, tolerance: float) -> bool:
    """Cone membership when every triple is singular (the cables span a plane or less)."""
    for size in (1, 2):
        for subset in combinations(range(u.shape[0]), size):
            basis = u[list(subset)].T
            coefficients, *_ = np.linalg.lstsq(basis, load, rcond=None)
            if (np.min(coefficients) >= -tolerance * np.linalg.norm(load)
                    and np.linalg.norm(basis @ coefficients - load) <= tolerance * np.linalg.norm(load)):
                return True
    return False


def closed_form_coverage(robot: Robot, points_per_axis: int = 9) -> tuple[int, int]:
    """On a grid of `points_per_axis`³ points over the workspace box, with the end-effector at
    rest: (points where S⁺ w is within [tension_min_n, tension_max_n], points where any
    tensions within those bounds hold it). Where the two differ, the paper's pseudo-inverse
    has no answer and the bounded minimum-norm distribution has one."""
    axes = [np.linspace(low, high, points_per_axis)
            for low, high in zip(robot.workspace_min_m, robot.workspace_max_m)]
    grid = np.stack(np.meshgrid(*axes, indexing='ij'), axis=-1).reshape(-1, 3)
    counts = []
    for method in (PseudoInverse, BoundedMinimumNorm):
        distribution = method(robot.tension_min_n, robot.tension_max_n)
        held = 0
        for position in grid:
            u, _ = cable_vectors(robot.exit_points_m, position)
            try:
                distribution.distribute(u.T, -robot.weight_wrench_n)
                held += 1
            except InfeasibleTensionError:
                pass
        counts.append(held)
    return counts[0], counts[1]
