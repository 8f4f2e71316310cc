"""Symmetric 3x3 solves by cofactors: J J^T systems of the 3x7 position Jacobian (motion layer) and the
innovation covariance S of the puck filter.

At this size numpy's LAPACK calls cost more in call overhead than the arithmetic, and the motion
layer makes tens of thousands of them per planned command (tracking, IK, hit posture).
"""
from __future__ import annotations

import numpy as np


def _cofactors(a: np.ndarray, damping: float) -> tuple[float, float, float, float, float, float, float]:
    """Cofactors (c00, c01, c02, c11, c12, c22) and determinant of ``a + damping I`` (upper triangle read)."""
    (a00, a01, a02), (_, a11, a12), (_, _, a22) = a.tolist()
    a00, a11, a22 = a00 + damping, a11 + damping, a22 + damping
    c00, c01, c02 = a11 * a22 - a12 * a12, a02 * a12 - a01 * a22, a01 * a12 - a02 * a11
    c11, c12, c22 = a00 * a22 - a02 * a02, a01 * a02 - a00 * a12, a00 * a11 - a01 * a01
    return c00, c01, c02, c11, c12, c22, a00 * c00 + a01 * c01 + a02 * c02


def inverse_sym3(a: np.ndarray, damping: float = 0.0) -> np.ndarray:
    """(a + damping I)^-1 of a symmetric 3x3 matrix ``a`` (only its upper triangle is read)."""
    c00, c01, c02, c11, c12, c22, det = _cofactors(a, damping)
    return np.array([[c00, c01, c02], [c01, c11, c12], [c02, c12, c22]]) / det


def solve_sym3(a: np.ndarray, b: np.ndarray, damping: float = 0.0) -> np.ndarray:
    """x with (a + damping I) x = b for a symmetric 3x3 ``a`` and a 3-vector ``b``."""
    c00, c01, c02, c11, c12, c22, det = _cofactors(a, damping)
    b0, b1, b2 = b.tolist()
    return np.array([c00 * b0 + c01 * b1 + c02 * b2, c01 * b0 + c11 * b1 + c12 * b2,
                     c02 * b0 + c12 * b1 + c22 * b2]) / det
