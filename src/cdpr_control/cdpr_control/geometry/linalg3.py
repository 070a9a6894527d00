"""Closed-form 3 × 3 solves: on matrices this small, LAPACK's call overhead dominates."""
from __future__ import annotations

import numpy as np


def solve3(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with matrix @ x = rhs, by Cramer's rule; rhs is (3,) or (3, k). A stack of
    matrices (n, 3, 3) takes a stack of right-hand sides (n, 3).

    Raises numpy.linalg.LinAlgError when a matrix is singular to working precision.
    """
    if matrix.ndim > 2:
        return _solve3_stack(matrix, rhs)
    adjugate, det = _adjugate_and_determinant(matrix.tolist())
    return (np.array(adjugate) @ rhs) / det


# A determinant this small against the largest entry cubed is singular.
SINGULAR_DETERMINANT_RATIO = 1e-14


def _adjugate_and_determinant(rows):
    adjugate, det = _cofactors(rows)
    (a, b, c), (d, e, f), (g, h, i) = rows
    scale = max(abs(a), abs(b), abs(c), abs(d), abs(e), abs(f), abs(g), abs(h), abs(i))
    if abs(det) <= SINGULAR_DETERMINANT_RATIO * scale ** 3:
        raise np.linalg.LinAlgError('singular 3 x 3 matrix')
    return adjugate, det


def _solve3_stack(matrices: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    adjugate, det = _cofactors(np.moveaxis(matrices, (-2, -1), (0, 1)))
    largest = np.max(np.abs(matrices), axis=(-2, -1))
    if np.any(np.abs(det) <= SINGULAR_DETERMINANT_RATIO * largest ** 3):
        raise np.linalg.LinAlgError('singular 3 x 3 matrix')
    return (np.einsum('ij...,...j->...i', np.array(adjugate), rhs)) / det[..., None]


def _cofactors(rows):
    """The adjugate (three rows of three) and the determinant of a 3 × 3 matrix given by
    its rows, of numbers or of arrays (one matrix per element)."""
    (a, b, c), (d, e, f), (g, h, i) = rows
    co_a, co_b, co_c = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * co_a + b * co_b + c * co_c
    adjugate = ((co_a, c * h - b * i, b * f - c * e),
                (co_b, a * i - c * g, c * d - a * f),
                (co_c, b * g - a * h, a * e - b * d))
    return adjugate, det
