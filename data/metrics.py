"""Metrics of the paper (eq. 9-10) and loop geometry.

``e_m`` and ``e_rms`` are eq. 10, returned in percent of the measured
peak-to-peak. ``fitness`` is eq. 9: sum_m k_m/n_m sum_i (y_mi - y^a_mi)^2.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np


def _span(y_measured: np.ndarray) -> float:
    span = float(np.max(y_measured) - np.min(y_measured))
    return span if span > 0 else float("nan")


def e_m(y_predicted, y_measured) -> float:
    """Maximum error, eq. 10, in percent of the measured peak-to-peak."""
    y, ya = np.asarray(y_predicted, float), np.asarray(y_measured, float)
    return 100.0 * float(np.max(np.abs(y - ya))) / _span(ya)


def e_rms(y_predicted, y_measured) -> float:
    """Root-mean-square error, eq. 10, in percent of the measured peak-to-peak."""
    y, ya = np.asarray(y_predicted, float), np.asarray(y_measured, float)
    return 100.0 * float(np.sqrt(np.mean((y - ya) ** 2))) / _span(ya)


def fitness(predictions: Sequence[np.ndarray], measurements: Sequence[np.ndarray], weights: Sequence[float]) -> float:
    """Eq. 9 over the scored samples of each record: sum_m k_m/n_m sum_i (y - y^a)^2."""
    total = 0.0
    for y, ya, k in zip(predictions, measurements, weights):
        y, ya = np.asarray(y, float), np.asarray(ya, float)
        total += k * float(np.mean((y - ya) ** 2))
    return total


def peak_to_peak(y) -> float:
    y = np.asarray(y, float)
    return float(np.max(y) - np.min(y))


def loop_width(u, y, n_grid: int = 2001) -> float:
    """Largest vertical opening between the descending and the ascending branch.

    ``u``, ``y`` hold one period. The period is split at the input's maximum
    and minimum into an ascending and a descending branch; both are
    interpolated on a common input grid over the range both cover, and the
    largest |y_desc - y_asc| is returned.
    """
    u, y = np.asarray(u, float), np.asarray(y, float)
    k0 = int(np.argmin(u))
    u, y = np.roll(u, -k0), np.roll(y, -k0)
    k1 = int(np.argmax(u))
    if k1 == 0 or k1 == u.size - 1:
        return 0.0
    asc_u, asc_y = u[: k1 + 1], y[: k1 + 1]
    des_u, des_y = np.append(u[k1:], u[0]), np.append(y[k1:], y[0])
    lo = max(asc_u.min(), des_u.min())
    hi = min(asc_u.max(), des_u.max())
    if not hi > lo:
        return 0.0
    grid = np.linspace(lo, hi, n_grid)
    oa, od = np.argsort(asc_u, kind="stable"), np.argsort(des_u, kind="stable")
    ya = np.interp(grid, asc_u[oa], asc_y[oa])
    yd = np.interp(grid, des_u[od], des_y[od])
    return float(np.max(np.abs(yd - ya)))
