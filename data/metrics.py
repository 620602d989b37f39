"""Metrics of the paper (eq. 9-10) and loop geometry.

``e_m`` and ``e_rms`` are eq. 10, returned in percent of the measured
peak-to-peak. ``fitness`` is eq. 9: sum_m k_m/n_m sum_i (y_mi - y^a_mi)^2.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np


def power_of_two_scale(values) -> float:
    """2^e with 2^e <= max |values| < 2^(e+1) (1 where all are zero or not finite). Dividing by it is exact in
    floating point, so data at any scale are computed at order one and results at order one are unchanged
    to the last bit."""
    a = np.abs(np.asarray(values, float))
    a = a[np.isfinite(a)]
    peak = float(a.max()) if a.size else 0.0
    if peak == 0.0:
        return 1.0
    return math.ldexp(0.5, math.frexp(peak)[1])


def _scaled(y_predicted, y_measured) -> tuple[np.ndarray, np.ndarray, float]:
    """(y, y^a) divided by the power of two of the measured output's scale, and the scaled span."""
    ya = np.asarray(y_measured, float)
    s = power_of_two_scale(ya)
    ya = ya / s
    span = float(np.max(ya) - np.min(ya))
    return np.asarray(y_predicted, float) / s, ya, span if span > 0 else float("nan")


def e_m(y_predicted, y_measured) -> float:
    """Maximum error, eq. 10, in percent of the measured peak-to-peak (scale-free: ``power_of_two_scale``)."""
    y, ya, span = _scaled(y_predicted, y_measured)
    return 100.0 * float(np.max(np.abs(y - ya))) / span


def e_rms(y_predicted, y_measured) -> float:
    """Root-mean-square error, eq. 10, in percent of the measured peak-to-peak (scale-free: the squares are
    summed at order one, so no output too small or large for its square underflows or overflows)."""
    y, ya, span = _scaled(y_predicted, y_measured)
    return 100.0 * float(np.sqrt(np.mean((y - ya) ** 2))) / span


def fitness(predictions: Sequence[np.ndarray], measurements: Sequence[np.ndarray], weights: Sequence[float]) -> float:
    """Eq. 9 over the scored samples of each record: sum_m k_m/n_m sum_i (y - y^a)^2, in the output's unit
    squared (summed at order one and scaled back, so it underflows only where the result itself does)."""
    measurements = [np.asarray(ya, float) for ya in measurements]
    s = power_of_two_scale(np.concatenate([ya.ravel() for ya in measurements]) if measurements else [])
    total = 0.0
    for y, ya, k in zip(predictions, measurements, weights):
        y = np.asarray(y, float)
        total += k * float(np.mean(((y - ya) / s) ** 2))
    return total * s * s


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
