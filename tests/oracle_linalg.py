"""Small dense linear-algebra helpers of the test oracles (only they need them)."""
from __future__ import annotations

import numpy as np


def symmetric_from_upper(M: np.ndarray) -> np.ndarray:
    """The symmetric matrices (..., n, n) whose upper triangles are those of M: Pinocchio fills
    only the upper triangle of the mass matrix (``crba``) and of ``Minv``."""
    return np.triu(M) + np.swapaxes(np.triu(M, 1), -1, -2)
