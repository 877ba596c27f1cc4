"""Robust weights of sec. 3.3 in plain NumPy (reference for tests; the tracker uses kernels).

Tukey weights, eq. (9)-(10), with the median of the absolute residuals and the constants
c = 1.4826, b = 4.6851; depth-consistency weights, eq. (11)-(12), with the depth noise tau.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

F64 = NDArray[np.float64]

TUKEY_C = 1.4826
TUKEY_B = 4.6851


def tukey_weights(e: F64, median_abs: float | None = None) -> F64:
    """Eq. (9)-(10); ``median_abs`` defaults to the exact median of |e|."""
    e_abs = np.abs(np.asarray(e, dtype=np.float64))
    med = float(np.median(e_abs)) if median_abs is None else float(median_abs)
    u = e_abs / (TUKEY_C * max(med, 1e-6))  # eq. (9)
    return np.where(u <= TUKEY_B, (1.0 - (u / TUKEY_B) ** 2) ** 2, 0.0)  # eq. (10)


def depth_weights(depth_measured_m: F64, depth_predicted_m: F64, tau_m: float) -> F64:
    """Eq. (11)-(12): e_z = Z(w(P; T)) - e3^T T P, w_z = max(1 - e_z^2 / tau^2, 0)^2."""
    ez = np.asarray(depth_measured_m, dtype=np.float64) - np.asarray(depth_predicted_m)
    return np.maximum(1.0 - ez * ez / (tau_m * tau_m), 0.0) ** 2
