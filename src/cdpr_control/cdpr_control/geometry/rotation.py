"""Orientation of a rigid platform: unit quaternions for the state, rotation vectors for
small differences (docs/platform.md).

A quaternion is (w, x, y, z), unit norm, and q and −q are one orientation; R(q) maps
platform-frame vectors to the world frame. Angular velocities ω are in the world frame.
Unit quaternions have no singular orientation, unlike Euler angles, whose pitch of ±90°
loses a degree of freedom; rotation vectors φ (axis × angle, rad) are used only for
differences between nearby orientations (a Newton step, a tracking error), where they
are well defined up to 180°.
"""
from __future__ import annotations

import math

import numpy as np

IDENTITY = np.array([1.0, 0.0, 0.0, 0.0])
IDENTITY.setflags(write=False)
# Below this angle (rad) sin(θ/2)/θ is taken from its series: 1/2 − θ²/48.
SMALL_ANGLE_RAD = 1e-6


def normalised(quaternion) -> np.ndarray:
    """The unit quaternion of `quaternion` (of each row of a stack), with w ≥ 0."""
    q = np.asarray(quaternion, dtype=float)
    if q.ndim == 1:
        w, x, y, z = q.tolist()
        norm = (w * w + x * x + y * y + z * z) ** 0.5
        if not 0.0 < norm < float('inf'):
            raise ValueError(f'not a rotation quaternion: {quaternion!r}')
        return q / (norm if w >= 0.0 else -norm)
    norm = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(norm == 0.0) or not np.all(np.isfinite(q)):
        raise ValueError(f'not a rotation quaternion: {quaternion!r}')
    q = q / norm
    return np.where(q[..., :1] < 0.0, -q, q)


def rotation_matrix(quaternion) -> np.ndarray:
    """R (3 × 3, or n × 3 × 3 for a stack) of a unit quaternion."""
    quaternion = np.asarray(quaternion, dtype=float)
    if quaternion.ndim == 1:
        # one pose, every tick: on plain floats, several times faster than numpy's stacking
        w, x, y, z = quaternion.tolist()
        return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                         [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                         [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    w, x, y, z = np.moveaxis(quaternion, -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=-2)


def product(first, second) -> np.ndarray:
    """The quaternion of rotating by `second`, then by `first` (R(q₁ q₂) = R(q₁) R(q₂))."""
    first, second = np.asarray(first, dtype=float), np.asarray(second, dtype=float)
    if first.ndim == 1 and second.ndim == 1:
        w1, x1, y1, z1 = first.tolist()
        w2, x2, y2, z2 = second.tolist()
        return np.array([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                         w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2])
    w1, x1, y1, z1 = np.moveaxis(first, -1, 0)
    w2, x2, y2, z2 = np.moveaxis(second, -1, 0)
    return np.stack([w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
                     w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
                     w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
                     w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2], axis=-1)


def conjugate(quaternion) -> np.ndarray:
    """The inverse rotation of a unit quaternion."""
    return np.asarray(quaternion, dtype=float) * np.array([1.0, -1.0, -1.0, -1.0])


def from_rotation_vector(rotation_vector_rad) -> np.ndarray:
    """The unit quaternion of a rotation by |φ| about φ/|φ| (φ in rad)."""
    phi = np.asarray(rotation_vector_rad, dtype=float)
    if phi.ndim == 1:
        x, y, z = phi.tolist()
        angle = (x * x + y * y + z * z) ** 0.5
        half_sinc = 0.5 - angle * angle / 48.0 if angle < SMALL_ANGLE_RAD else math.sin(0.5 * angle) / angle
        return np.array([math.cos(0.5 * angle), half_sinc * x, half_sinc * y, half_sinc * z])
    angle = np.linalg.norm(phi, axis=-1, keepdims=True)
    small = angle < SMALL_ANGLE_RAD
    half_sinc = np.where(small, 0.5 - angle * angle / 48.0,
                         np.sin(0.5 * angle) / np.where(small, 1.0, angle))
    return np.concatenate([np.cos(0.5 * angle), half_sinc * phi], axis=-1)


def to_rotation_vector(quaternion) -> np.ndarray:
    """φ (rad) of a unit quaternion, the angle in [0, π]."""
    q = normalised(quaternion)
    vector = q[..., 1:]
    sine = np.linalg.norm(vector, axis=-1, keepdims=True)
    angle = 2.0 * np.arctan2(sine, q[..., :1])
    small = sine < SMALL_ANGLE_RAD
    return vector * np.where(small, 2.0, angle / np.where(small, 1.0, sine))


def difference(target, current) -> np.ndarray:
    """φ (rad, world frame) that turns `current` into `target`: R(target) = R(φ) R(current)."""
    return to_rotation_vector(product(target, conjugate(current)))


def from_axis_angle(axis, angle_rad: float) -> np.ndarray:
    """The unit quaternion of a rotation by `angle_rad` about `axis` (any length > 0)."""
    axis = np.asarray(axis, dtype=float)
    norm = np.linalg.norm(axis)
    if norm == 0.0:
        raise ValueError('a rotation axis must not be zero')
    return from_rotation_vector(axis / norm * angle_rad)


def cross_rows(first: np.ndarray, second: np.ndarray) -> np.ndarray:
    """Row-wise cross products of two m × 3 arrays (np.cross costs twice as much on a few rows)."""
    a0, a1, a2 = first[:, 0], first[:, 1], first[:, 2]
    b0, b1, b2 = second[:, 0], second[:, 1], second[:, 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=1)


def tilt_rad(quaternion) -> float | np.ndarray:
    """The angle (rad) between the platform's z axis and the world's."""
    return np.arccos(np.clip(rotation_matrix(quaternion)[..., 2, 2], -1.0, 1.0))
