"""Kinematics of a point-mass cable robot (docs/design.md §4 sign conventions).

r_i = A_i − p, d_i = |r_i|, u_i = r_i / d_i; structure matrix S = [u_1 … u_m] (3 × m).
l_i = l_i0 + ρ θ_i, l̇ = −Sᵀ ṗ, θ̇ = −Sᵀ ṗ / ρ, θ̈ = −(Sᵀ p̈ + Ṡᵀ ṗ) / ρ.

The functions from `cable_vectors` to `joint_acceleration` take one pose or a stack of
them (leading axes, e.g. (n, 3) positions give (n, 3, m) structure matrices): a
reference is tabulated a whole trajectory at once, where a loop over its rows spends
nearly all its time in numpy's per-call overhead.
"""
from __future__ import annotations

import numpy as np

from cdpr_control.geometry.linalg3 import solve3
from cdpr_control.model.body import KinematicsError
from cdpr_control.model.robot import Robot

FK_ITERATIONS = 20
FK_TOLERANCE_M = 1e-13


def cable_vectors(exit_points_m: np.ndarray, position_m: np.ndarray):
    """Unit vectors u_i (m × 3, end-effector → exit point) and lengths d_i (m)."""
    r = exit_points_m - np.asarray(position_m)[..., None, :]
    d = np.sqrt(np.einsum('...ij,...ij->...i', r, r))
    return r / d[..., None], d


def structure_matrix(robot: Robot, position_m: np.ndarray):
    """S (3 × m) and the straight-line cable lengths d (m) at `position_m`."""
    u, d = cable_vectors(robot.exit_points_m, position_m)
    return np.swapaxes(u, -1, -2), d


def structure_matrix_rate(structure: np.ndarray, lengths_m: np.ndarray,
                          velocity_m_s: np.ndarray) -> np.ndarray:
    """Ṡ (3 × m): u̇_i = −(I − u_i u_iᵀ) ṗ / d_i."""
    along = _transposed_times(structure, velocity_m_s)
    return (structure * along[..., None, :] - velocity_m_s[..., :, None]) / lengths_m[..., None, :]


def inverse_kinematics(robot: Robot, position_m: np.ndarray) -> np.ndarray:
    """Motor angles θ (rad) that put the end-effector at `position_m`."""
    _, d = cable_vectors(robot.exit_points_m, position_m)
    return (d - robot.cable_length_offset_m) / robot.motor.drum_radius_m


def joint_velocity(structure: np.ndarray, velocity_m_s: np.ndarray, drum_radius_m: float):
    """θ̇ = −Sᵀ ṗ / ρ (rad/s)."""
    return -_transposed_times(structure, velocity_m_s) / drum_radius_m


def joint_acceleration(structure: np.ndarray, structure_rate: np.ndarray,
                       velocity_m_s: np.ndarray, acceleration_m_s2: np.ndarray,
                       drum_radius_m: float) -> np.ndarray:
    """θ̈ = −(Sᵀ p̈ + Ṡᵀ ṗ) / ρ (rad/s²)."""
    return -(_transposed_times(structure, acceleration_m_s2)
             + _transposed_times(structure_rate, velocity_m_s)) / drum_radius_m


def _transposed_times(matrix: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """Mᵀ v for a 3 × m matrix and a 3-vector, or for stacks of them."""
    return np.einsum('...ij,...i->...j', matrix, vector)


def forward_kinematics(robot: Robot, angles_rad: np.ndarray, cables: np.ndarray | None = None):
    """End-effector position from the motor angles of the `cables` (boolean mask); of
    each row for a stack of angles (n × m gives n × 3), as a recorded run is read.

    Subtracting the first sphere |A_1 − p| = l_1 from the others leaves linear equations
    G p = h. With exit points in general position and m ≥ 4 they fix p; with coplanar
    exit points (or 3 cables) they fix a line normal to that plane, which meets the
    first sphere at two mirror points, and the one below the exit points is taken (a
    suspended robot hangs). Gauss–Newton then fits all lengths in the geometric
    least-squares sense, which matters when they carry noise.
    """
    if cables is None:
        cables = np.ones(robot.cable_count, dtype=bool)
    exit_points = robot.exit_points_m[cables]
    if exit_points.shape[0] < 3:
        raise KinematicsError(f'forward kinematics needs 3 cables, got {exit_points.shape[0]}')
    lengths = (robot.cable_length_offset_m[cables]
               + robot.motor.drum_radius_m * np.asarray(angles_rad, dtype=float)[..., cables])
    position = _sphere_intersection(exit_points, lengths)
    if lengths.ndim == 1:
        return _refine(exit_points, lengths, position)
    return _refine_rows(exit_points, lengths, position)


class _SphereSystem:
    """The linear part of the sphere equations, which depends only on the exit points."""

    def __init__(self, exit_points: np.ndarray):
        self.first = exit_points[0].copy()
        self.squared_norms = np.einsum('ij,ij->i', exit_points, exit_points)
        g = 2.0 * (exit_points[1:] - self.first)
        eigenvalues, basis = np.linalg.eigh(g.T @ g)
        if eigenvalues[1] <= 1e-9 * eigenvalues[2]:
            raise KinematicsError('exit points of the given cables are collinear')
        self.coplanar = eigenvalues[0] <= 1e-9 * eigenvalues[2]
        kept = basis[:, 1:] if self.coplanar else basis
        inverse = 1.0 / (eigenvalues[1:] if self.coplanar else eigenvalues)
        # h ↦ least-squares (or in-plane minimum-norm) solution of G p = h
        self.solution_map = (kept * inverse) @ kept.T @ g.T
        self.normal = basis[:, 0]


_SPHERE_SYSTEMS: dict[bytes, _SphereSystem] = {}


def _sphere_system(exit_points: np.ndarray) -> _SphereSystem:
    key = exit_points.tobytes()
    system = _SPHERE_SYSTEMS.get(key)
    if system is None:
        system = _SPHERE_SYSTEMS[key] = _SphereSystem(exit_points)
    return system


def _sphere_intersection(exit_points: np.ndarray, lengths: np.ndarray) -> np.ndarray:
    """The spheres' point of one set of lengths (k,), or of each row of a stack (n × k)."""
    system = _sphere_system(exit_points)
    squared = system.squared_norms - lengths * lengths
    position = np.einsum('ij,...j->...i', system.solution_map, squared[..., 1:] - squared[..., :1])
    if not system.coplanar:
        return position
    on_plane = position - system.first
    # |q + t n|² = l_1² : t² + 2 (n·q) t + |q|² − l_1² = 0, q = p − A_1
    half_b = on_plane @ system.normal
    discriminant = np.maximum(half_b * half_b - np.einsum('...i,...i->...', on_plane, on_plane)
                              + lengths[..., 0] ** 2, 0.0)
    below = position + (-half_b - np.sqrt(discriminant))[..., None] * system.normal
    above = position + (-half_b + np.sqrt(discriminant))[..., None] * system.normal
    return np.where((below[..., 2] <= above[..., 2])[..., None], below, above)


def _refine(exit_points: np.ndarray, lengths: np.ndarray, position: np.ndarray) -> np.ndarray:
    """Gauss–Newton from `position` (3,) to the lengths (k,). A pose at a time is what the
    nodes ask, every tick: on one row `_refine_rows` costs ~3x for numpy's indexing."""
    for _ in range(FK_ITERATIONS):
        u, d = cable_vectors(exit_points, position)
        residual = d - lengths
        if np.max(np.abs(residual)) < FK_TOLERANCE_M:
            break
        step = _gauss_newton_step(u, residual)
        if np.max(np.abs(step)) < FK_TOLERANCE_M:
            break
        position = position + step
    return position


def _refine_rows(exit_points: np.ndarray, lengths: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """`_refine` of each row of a stack (n × 3, n × k): the rows still off their lengths
    take their steps together, each stopping where `_refine` would."""
    positions = positions.copy()
    rows = np.arange(positions.shape[0])
    for _ in range(FK_ITERATIONS):
        u, d = cable_vectors(exit_points, positions[rows])
        residual = d - lengths[rows]
        off = np.max(np.abs(residual), axis=-1) >= FK_TOLERANCE_M
        rows, u, residual = rows[off], u[off], residual[off]
        if rows.size == 0:
            break
        steps = _gauss_newton_steps(u, residual)
        moving = np.max(np.abs(steps), axis=-1) >= FK_TOLERANCE_M
        rows = rows[moving]
        if rows.size == 0:
            break
        positions[rows] += steps[moving]
    return positions


def _gauss_newton_steps(u: np.ndarray, residual: np.ndarray) -> np.ndarray:
    """δ of the normal equations uᵀu δ = uᵀ r (∂d_i/∂p = −u_iᵀ), for a stack of rows."""
    u_t = np.swapaxes(u, -1, -2)
    try:
        return solve3(u_t @ u, np.einsum('...ij,...j->...i', u_t, residual))
    except np.linalg.LinAlgError:
        return np.array([_gauss_newton_step(*row) for row in zip(u, residual)])


def _gauss_newton_step(u: np.ndarray, residual: np.ndarray) -> np.ndarray:
    try:
        return solve3(u.T @ u, u.T @ residual)
    except np.linalg.LinAlgError:
        # Lengths whose spheres do not meet (stale or inconsistent angles) start it in
        # the plane of the exit points, where the directions span that plane only: the
        # least-squares step within it.
        return np.linalg.lstsq(u, residual, rcond=None)[0]
