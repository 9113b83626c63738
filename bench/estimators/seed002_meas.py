"""The residual chi-square fault test of seed 002 (section 5.3, eq. 18-20), compiled.

:func:`tested_update` tests a displacement-increment measurement ``z = H x + w``
(rows right, forward, up; the prior estimate zero after closed-loop feedback, so the
innovation is ``z``) before it updates the filter, by one or two layers:

1. ``lambda = z' S^-1 z`` with ``S = H P H' + R`` against ``g3`` (chi-square, 3 dof):
   passed, the whole measurement updates;
2. (two layers) failed, the lateral and vertical rows alone (``J`` = rows 1 and 3 of
   ``H``) against ``g2`` (2 dof): passed, they update (the kinematic constraint; the
   odometer's travel excluded, class 1, longitudinal); failed, no update, class 2
   (lateral) or 3 (vertical) by the larger normalised residual;
3. (one layer) failed: no update, the class of the largest normalised component.

Updates are Joseph-form with solves (:func:`bench.estimators.kf.joseph_update`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from bench.estimators.kf import joseph_update, nis

__all__ = ["NONE", "SINGLE_LAYER", "TWO_LAYER", "UPDATED_ALL", "UPDATED_CONSTRAINT", "NOT_UPDATED", "tested_update"]

#: detection settings (the kernel's ``P_DET``)
NONE, SINGLE_LAYER, TWO_LAYER = 0.0, 1.0, 2.0
#: what :func:`tested_update` did
UPDATED_ALL, UPDATED_CONSTRAINT, NOT_UPDATED = 0, 1, 2


@njit(cache=True)
def tested_update(P: np.ndarray, x: np.ndarray, z: np.ndarray, H: np.ndarray, R: np.ndarray, det: float,
                  g3: float, g2: float) -> tuple[int, int, float]:
    """Test and apply the measurement (module docstring): ``x`` (n,) gets the estimate,
    ``P`` the posterior. Returns (what was done, the ICD fault class 0-3, the first
    layer's statistic; 0 without detection)."""
    if det == NONE:
        joseph_update(x, P, z, H, R)
        return UPDATED_ALL, 0, 0.0
    S = H @ P @ H.T + R
    lam = nis(z, S)
    if lam <= g3:
        joseph_update(x, P, z, H, R)
        return UPDATED_ALL, 0, lam
    a0 = abs(z[0]) / math.sqrt(S[0, 0])
    a1 = abs(z[1]) / math.sqrt(S[1, 1])
    a2 = abs(z[2]) / math.sqrt(S[2, 2])
    if det == TWO_LAYER:
        n = P.shape[0]
        J = np.zeros((2, n))
        for j in range(n):
            J[0, j] = H[0, j]
            J[1, j] = H[2, j]
        zj = np.array([z[0], z[2]])
        Rj = np.array([[R[0, 0], R[0, 2]], [R[2, 0], R[2, 2]]])
        if nis(zj, J @ P @ J.T + Rj) <= g2:
            joseph_update(x, P, zj, J, Rj)
            return UPDATED_CONSTRAINT, 1, lam
        return NOT_UPDATED, (2 if a0 >= a2 else 3), lam
    if a1 >= a0 and a1 >= a2:
        return NOT_UPDATED, 1, lam
    return NOT_UPDATED, (2 if a0 >= a2 else 3), lam
