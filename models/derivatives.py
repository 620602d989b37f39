"""Derivative estimates of a sampled input.

``backward`` is the paper's default: du/dt = [u(k) - u(k-1)] / T (section 3.2),
and, as our reading for the second derivative the paper does not specify,
the second backward difference [u(k) - 2u(k-1) + u(k-2)] / T^2. Before the
first sample the input is held at u(0), so both derivatives start at zero.

``smoothed`` survives noisy or quantised measured inputs: Savitzky-Golay
differentiation (a local cubic fit over a window given in seconds; the same
smoother pysindy's SmoothedFiniteDifference applies). It is non-causal (uses samples on both sides), which is
fine for identification from recorded data.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter

from .errors import ModelError

DERIVATIVE_METHODS = ("backward", "smoothed")


def backward_derivatives(u: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """First and second backward differences, with u(-1) = u(-2) = u(0)."""
    u = np.asarray(u, dtype=float)
    padded = np.concatenate((u[:1], u[:1], u))
    du = (padded[2:] - padded[1:-1]) / dt
    ddu = (padded[2:] - 2.0 * padded[1:-1] + padded[:-2]) / (dt * dt)
    return du, ddu


def backward_second_difference_at(u: np.ndarray, dt: float, rows: np.ndarray) -> np.ndarray:
    """The second backward difference of ``backward_derivatives`` at the samples ``rows`` only."""
    u = np.asarray(u, dtype=float)
    return (u[rows] - 2.0 * u[np.maximum(rows - 1, 0)] + u[np.maximum(rows - 2, 0)]) / (dt * dt)


def smoothed_derivatives(u: np.ndarray, dt: float, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Savitzky-Golay (cubic) first and second derivatives over ``window_s`` seconds."""
    u = np.asarray(u, dtype=float)
    n = u.size
    window = int(round(window_s / dt)) | 1  # odd
    window = max(5, min(window, n - 1 if (n - 1) % 2 else n - 2))
    if window < 5:
        return backward_derivatives(u, dt)
    du = savgol_filter(u, window, 3, deriv=1, delta=dt, mode="interp")
    ddu = savgol_filter(u, window, 3, deriv=2, delta=dt, mode="interp")
    return du, ddu


def derivatives(u: np.ndarray, dt: float, method: str = "backward", window_s: float = 0.05):
    """(du/dt, d2u/dt2) by the named method."""
    if method == "backward":
        return backward_derivatives(u, dt)
    if method == "smoothed":
        return smoothed_derivatives(u, dt, window_s)
    raise ModelError(f"unknown derivative method {method!r}; choose one of {', '.join(DERIVATIVE_METHODS)}")
