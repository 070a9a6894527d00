"""Closed-form 3 × 3 solves: on matrices this small, LAPACK's call overhead dominates."""
from __future__ import annotations

import numpy as np


def solve3(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """x with matrix @ x = rhs, by Cramer's rule; rhs is (3,) or (3, k).

    Raises numpy.linalg.LinAlgError when the matrix is singular to working precision.
    """
    (a, b, c), (d, e, f), (g, h, i) = matrix.tolist()
    co_a, co_b, co_c = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * co_a + b * co_b + c * co_c
    scale = max(abs(a), abs(b), abs(c), abs(d), abs(e), abs(f), abs(g), abs(h), abs(i))
    if abs(det) <= 1e-14 * scale ** 3:
        raise np.linalg.LinAlgError('singular 3 x 3 matrix')
    inverse = np.array([[co_a, c * h - b * i, b * f - c * e],
                        [co_b, a * i - c * g, c * d - a * f],
                        [co_c, b * g - a * h, a * e - b * d]])
    return (inverse @ rhs) / det
