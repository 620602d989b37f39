"""Numba kernels of the linear dynamic blocks that extend a hysteresis model.

The first-order block starts from rest: the signal it filters is zero before
the record's first sample and jumps to its first value at t = 0 (an actuator at
rest before the record, as the play operators' zero initial state). The
second-order block (a mechanical mode) starts at rest at its signal's first
value: the mode is in equilibrium with the output the record starts from
(for a signal that starts at zero the two are the same; a mode started from
zero would ring at every record's start, which a recording cut from continuous
operation or held at a bias before it does not show). Between
samples the filtered signal is taken linear (first-order hold), and each block
is discretised exactly for that (no half-sample lag, unlike a zero-order hold):

* first-order low-pass  tau x' = v - x:
      x[k+1] = a x[k] + b0 v[k] + b1 v[k+1],  a = exp(-h / tau),
      b1 = 1 - (tau / h)(1 - a),  b0 = (1 - a) - b1,  x[0] = 0.
* second-order low-pass (unit static gain) x'' + 2 zeta w x' + w^2 x = w^2 v,
  state s = (x, x'):  s[k+1] = Phi s[k] + G0 v[k] + G1 v[k+1],  s[0] = (v[0], 0),
  Phi, G0, G1 from the matrix exponential (``second_order_foh``).
"""

from __future__ import annotations

import math

import numpy as np
import scipy.linalg
from numba import njit, prange


# --- coefficients ----------------------------------------------------------------
def first_order_foh(tau: float, h: float) -> tuple[float, float, float]:
    """(a, b0, b1) of the exact first-order-hold discretisation of tau x' = v - x."""
    r = h / tau
    a = math.exp(-r)
    one_minus_a = -math.expm1(-r)
    b1 = 1.0 - one_minus_a / r if r > 1e-8 else 0.5 * r  # series for tiny steps
    return a, one_minus_a - b1, b1


def second_order_foh(natural_frequency_hz: float, damping_ratio: float, h: float):
    """(Phi (2, 2), G0 (2,), G1 (2,)) of the exact first-order-hold discretisation of
    x'' + 2 zeta w x' + w^2 x = w^2 v with w = 2 pi f_n."""
    w = 2.0 * math.pi * natural_frequency_hz
    A = np.array([[0.0, 1.0], [-w * w, -2.0 * damping_ratio * w]])
    B = np.array([0.0, w * w])
    M = np.zeros((4, 4))
    M[:2, :2] = A * h
    M[:2, 2] = B * h
    M[2, 3] = 1.0
    E = scipy.linalg.expm(M)
    Phi, Ga, Gb = E[:2, :2], E[:2, 2], E[:2, 3]  # Ga = int e^{A s} B ds, Gb = the ramp part
    return np.ascontiguousarray(Phi), np.ascontiguousarray(Ga - Gb), np.ascontiguousarray(Gb)


# --- kernels ---------------------------------------------------------------------
@njit(cache=True, inline="always")
def _step1(a, b0, b1, x, vk, vn):
    # one first-order-hold step of the first-order block: x at the next sample
    return a * x + b0 * vk + b1 * vn


@njit(cache=True)
def _lowpass1(v, a, b0, b1, out):
    x = 0.0
    out[0] = 0.0
    for k in range(v.shape[0] - 1):
        x = _step1(a, b0, b1, x, v[k], v[k + 1])
        out[k + 1] = x


@njit(cache=True, nogil=True)
def lowpass1_bank_advance(state, coef, powers, u):
    """One sample of a weighted bank of first-order blocks for a stepper, block j filtering u^p_j
    (``_step1``, the step ``_lowpass1`` takes; from rest: 0 at the first sample). state = [first,
    x_1..x_m, u(k-1)]; coef = [a (m), b0 (m), b1 (m), weights (m)]. Returns sum_j w_j x_j(k)."""
    m = powers.shape[0]
    first = state[0] != 0.0
    u1 = state[m + 1]
    acc = 0.0
    for j in range(m):
        p = powers[j]
        x = 0.0 if first else _step1(coef[j], coef[m + j], coef[2 * m + j], state[1 + j], u1**p, u**p)
        state[1 + j] = x
        acc += coef[3 * m + j] * x
    state[0] = 0.0
    state[m + 1] = u
    return acc


@njit(cache=True)
def lowpass1(v, a, b0, b1):
    """First-order low-pass of v from rest, shape (T,)."""
    out = np.empty(v.shape[0])
    _lowpass1(v, a, b0, b1, out)
    return out


@njit(cache=True, parallel=True)
def lowpass1_bank(v, a, b0, b1):
    """One signal through several first-order low-passes (coefficient arrays (m,)): (m, T)."""
    m = a.shape[0]
    out = np.empty((m, v.shape[0]))
    for j in prange(m):
        _lowpass1(v, a[j], b0[j], b1[j], out[j])
    return out


@njit(cache=True)
def _lowpass1_at(v, a, b0, b1, rows, out):
    # _lowpass1's recurrence, the output kept at the sorted, distinct sample indices ``rows`` only
    x = 0.0
    j = 0
    while j < rows.shape[0] and rows[j] == 0:
        out[j] = 0.0
        j += 1
    for k in range(v.shape[0] - 1):
        if j == rows.shape[0]:
            break
        x = _step1(a, b0, b1, x, v[k], v[k + 1])
        if rows[j] == k + 1:
            out[j] = x
            j += 1


@njit(cache=True, parallel=True)
def lowpass1_bank_at(v, a, b0, b1, rows):
    """``lowpass1_bank`` kept at the sorted, distinct sample indices ``rows``: (m, rows.size)."""
    m = a.shape[0]
    out = np.empty((m, rows.shape[0]))
    for j in prange(m):
        _lowpass1_at(v, a[j], b0[j], b1[j], rows, out[j])
    return out


@njit(cache=True, inline="always")
def _step2(phi, g0, g1, x0, x1, vk, vn):
    # one first-order-hold step of the second-order block: the state (x, x') at the next sample
    return (phi[0, 0] * x0 + phi[0, 1] * x1 + g0[0] * vk + g1[0] * vn,
            phi[1, 0] * x0 + phi[1, 1] * x1 + g0[1] * vk + g1[1] * vn)


def lowpass2_coefficients(phi, g0, g1) -> np.ndarray:
    """Phi, G0, G1 packed in one array of 8 (``lowpass2_advance``: few arguments dispatch fast)."""
    return np.ascontiguousarray(np.concatenate((np.ravel(phi), g0, g1)), dtype=float)


@njit(cache=True, nogil=True)
def lowpass2_advance(state, coef, v):
    """One sample of the second-order block for a stepper: state = [first, x, x', v(k-1)] moves to
    sample k for the signal's value v there (``_step2``, the step ``_lowpass2`` takes; the first
    sample starts the mode at rest at v); coef from ``lowpass2_coefficients``. Returns x(k)."""
    if state[0] != 0.0:
        state[0] = 0.0
        state[1] = v
        state[2] = 0.0
    else:
        state[1], state[2] = _step2(coef[0:4].reshape((2, 2)), coef[4:6], coef[6:8], state[1], state[2],
                                    state[3], v)
    state[3] = v
    return state[1]


@njit(cache=True)
def _lowpass2(v, phi, g0, g1, out):
    # at rest at the first sample's level (a mode in equilibrium with the output it starts from)
    x0 = v[0]
    x1 = 0.0
    out[0] = x0
    for k in range(v.shape[0] - 1):
        x0, x1 = _step2(phi, g0, g1, x0, x1, v[k], v[k + 1])
        out[k + 1] = x0


@njit(cache=True, parallel=True)
def lowpass2_rows(V, phi, g0, g1):
    """Every row of V (m, T) through the same second-order low-pass: (m, T)."""
    out = np.empty_like(V)
    for j in prange(V.shape[0]):
        _lowpass2(V[j], phi, g0, g1, out[j])
    return out


@njit(cache=True)
def _lowpass2_at(v, phi, g0, g1, rows, out):
    # _lowpass2's recurrence, the output kept at the sorted, distinct sample indices ``rows`` only
    x0 = v[0]
    x1 = 0.0
    j = 0
    while j < rows.shape[0] and rows[j] == 0:
        out[j] = x0
        j += 1
    for k in range(v.shape[0] - 1):
        if j == rows.shape[0]:
            break
        x0, x1 = _step2(phi, g0, g1, x0, x1, v[k], v[k + 1])
        if rows[j] == k + 1:
            out[j] = x0
            j += 1


@njit(cache=True, parallel=True)
def lowpass2_columns_at(columns, phi, g0, g1, rows):
    """Each signal of ``columns`` (a numba typed List of (T,) arrays) through the same second-order low-pass,
    kept at the sorted, distinct sample indices ``rows``: (m, rows.size), without stacking the signals."""
    m = len(columns)
    out = np.empty((m, rows.shape[0]))
    for j in prange(m):
        _lowpass2_at(columns[np.int64(j)], phi, g0, g1, rows, out[j])
    return out


@njit(cache=True, parallel=True)
def lowpass2_sets(V, phis, g0s, g1s):
    """Row j of V (n, T) through its own second-order low-pass (phis (n, 2, 2)): (n, T)."""
    out = np.empty_like(V)
    for j in prange(V.shape[0]):
        _lowpass2(V[j], phis[j], g0s[j], g1s[j], out[j])
    return out
