"""Bouc-Wen oscillator (registry name ``bouc-wen-oscillator``): the structure of the
Bouc-Wen identification benchmark (Noel & Schoukens 2016), force u -> displacement y:

    m y'' + c y' + k y + z = u
    z'   = alpha y' - beta (gamma |y'| |z|^(nu-1) z + delta y' |z|^nu),     y = y' = z = 0 at t = 0

Parameters (names as in the benchmark): m, c, k, alpha, gamma, delta, and nu when
``fixed_nu`` is None (default: nu fixed at 1, the benchmark's value).

Identifiability. The force equation fixes z's scale (its coefficient is 1), so
alpha is identifiable; but beta multiplies both gamma and delta:
(beta, gamma, delta) -> (s beta, gamma / s, delta / s) leaves y unchanged. Only
beta gamma and beta delta are identifiable, so beta is a hyperparameter (default
the published 1e3; for nu = 1 its unit is 1 / output unit: m^-1 on the benchmark) and
gamma, delta are identified at that beta. m, c, k, alpha, gamma, delta (and nu) are
then identifiable from a record that drives the hysteresis (k and alpha separately
only through the hysteretic part: with gamma = delta = 0, z = alpha y and only
k + alpha counts).

Integration: classical RK4 in ``n_substeps`` fixed sub-steps per sample interval
(default 20: the benchmark's 15 kHz for 750 Hz data), in numba, parallel over
parameter sets. RK4 needs the force at the sub-step ends and mid-points; how it
is taken between samples is the hyperparameter ``input_interpolation``:

* ``"fourier"`` (default): the record's band-limited (trigonometric) interpolation,
  by zero-padding its FFT. This matches how the benchmark makes its signals:
  its script (BoucWen_ExampleIntegration.m, in forgi86/dynonet examples/BW/BoucWenFiles)
  builds the multisine directly at the 15 kHz integration rate from spectral lines
  below 150 Hz, integrates, low-pass filters (decimate, FIR) and keeps every 20th
  sample; so for a periodic multisine the 750 Hz samples determine the 15 kHz force
  exactly. A record that is not periodic (the sine sweep) rings near its ends.
* ``"linear"``: linear between samples; ``"hold"``: u[k] over interval k.

With the published parameters, fourier predicts the official validation multisine
(in steady state) within 2.4e-7 m, linear 7.3e-6 m, hold 1.1e-4 m
(results/bouc_wen_benchmark.md). The benchmark integrates with a Newmark scheme;
at 15 kHz (omega h ~ 0.015) both schemes are far more accurate than the data.

RK4 is second order here, not fourth: the right side kinks where y' or z changes sign.
Against scipy's solve_ivp (DOP853, rtol 1e-11) on the benchmark's parameters the
largest error is 1.2e-5 of max |y| at 20 sub-steps and 5e-7 at 100 (tests), far below
the benchmark's noise (about 1 % of the output's RMS).

Stepping: "linear" and "hold" are causal (the force within an interval needs only its two end
samples), so ``stepper`` gives a constant-time ``OscillatorStepper`` that runs the batch kernel's
per-interval ``_interval``, bit for bit as ``simulate``. "fourier" interpolates with the whole
record (a later sample changes the force between earlier ones): it has no stepper and says so
(``noncausal_reason``); a stepper would be a different model, fitted as such.

A set whose state leaves |y|, |z| < STATE_CAP or turns non-finite gives NaN from
there on (identifiers count and reject such sets).

Starts: ``linear_start`` fits m, c and k + alpha by linear least squares on a
record (finite-difference velocity and acceleration), the start from which
``lsq`` identifies the rest; ``bounds_around`` gives bounds scaled to that start.
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np
from numba import njit, prange

from .base import DataScale, HysteresisModel, Parameter
from .errors import ModelError
from .hyperparameters import check_choice, check_int, check_number
from .stepper import ArrayStepper

INTERPOLATIONS = ("fourier", "linear", "hold")
STATE_CAP = 1e12
SHAPE_BOUND = 50.0  # |beta gamma|, |beta delta| <= SHAPE_BOUND / max|y| (for nu = 1)
STIFFNESS_BOUND = 20.0  # k, alpha <= STIFFNESS_BOUND * max|u| / max|y|
NU_MAX = 4.0


@njit(cache=True, nogil=True, inline="always")
def _rates(y, v, z, u, m, c, k, alpha, bg, bd, nu):
    acc = (u - c * v - k * y - z) / m
    az = abs(z)
    p = az if nu == 1.0 else az**nu
    sz = 1.0 if z > 0.0 else (-1.0 if z < 0.0 else 0.0)
    zd = alpha * v - p * (bg * abs(v) * sz + bd * v)
    return v, acc, zd


@njit(cache=True, nogil=True, inline="always")
def _interval(u_fine, base, n_sub, h, y, v, z, m, c, k, alpha, bg, bd, nu):
    """(y, v, z) at the end of one sample interval: n_sub RK4 sub-steps of length h, the force at
    u_fine[base : base + 2 n_sub + 1] (sub-step ends and mid-points, the interval's end as a left limit).
    The per-sample update of both the batch kernel and the stepper."""
    for j in range(n_sub):
        i = base + 2 * j
        u0 = u_fine[i]
        u1 = u_fine[i + 1]
        u2 = u_fine[i + 2]
        k1y, k1v, k1z = _rates(y, v, z, u0, m, c, k, alpha, bg, bd, nu)
        k2y, k2v, k2z = _rates(y + 0.5 * h * k1y, v + 0.5 * h * k1v, z + 0.5 * h * k1z, u1,
                               m, c, k, alpha, bg, bd, nu)
        k3y, k3v, k3z = _rates(y + 0.5 * h * k2y, v + 0.5 * h * k2v, z + 0.5 * h * k2z, u1,
                               m, c, k, alpha, bg, bd, nu)
        k4y, k4v, k4z = _rates(y + h * k3y, v + h * k3v, z + h * k3z, u2, m, c, k, alpha, bg, bd, nu)
        y += h * (k1y + 2.0 * k2y + 2.0 * k3y + k4y) / 6.0
        v += h * (k1v + 2.0 * k2v + 2.0 * k3v + k4v) / 6.0
        z += h * (k1z + 2.0 * k2z + 2.0 * k3z + k4z) / 6.0
    return y, v, z


@njit(cache=True, nogil=True, inline="always")
def _capped(y, v, z):
    """Whether the state left the cap (or turned non-finite): NaN from the next sample on."""
    return not (abs(y) < STATE_CAP and abs(z) < STATE_CAP and abs(v) < STATE_CAP)


@njit(cache=True, nogil=True)
def _simulate_one(u_fine, n_sub, dt, m, c, k, alpha, bg, bd, nu, start, stop, out):
    """y(k) for k in [start, stop) into ``out``; u_fine holds, per sample interval, the force at
    2 n_sub + 1 equally spaced times from its start to its end (left limit)."""
    h = dt / n_sub
    y = 0.0
    v = 0.0
    z = 0.0
    for n in range(stop):
        if n >= start:
            out[n - start] = y
        if n == stop - 1:
            break
        y, v, z = _interval(u_fine, (2 * n_sub + 1) * n, n_sub, h, y, v, z, m, c, k, alpha, bg, bd, nu)
        if _capped(y, v, z):
            for j in range(max(n + 1, start), stop):
                out[j - start] = math.nan
            return


@njit(cache=True, nogil=True)
def oscillator_advance(u, state, coef, fine):
    """One sample of ``OscillatorStepper``: state [first, u(k-1), y, v, z, failed, k] moves to sample k
    for the force u there; returns y(k). The force within the interval is ``fine_input``'s for that
    interval alone (coef[1] = 1: linear, ``np.interp``'s arithmetic at the batch grid's positions;
    0: hold), then ``_interval`` as the batch kernel. coef = [dt, n_sub, linear, m, c, k, alpha,
    beta gamma, beta delta, nu]; fine: scratch of 2 n_sub + 1."""
    if state[0] != 0.0:  # the record's first sample: at rest
        state[0] = 0.0
        state[1] = u
        state[6] = 1.0
        return state[2]
    u_prev = state[1]
    i = state[6] - 1.0  # the interval's index (a whole number)
    state[1] = u
    state[6] += 1.0
    if state[5] != 0.0:
        return math.nan
    n_sub = int(coef[1])
    factor = 2 * n_sub
    if coef[2] != 0.0:
        slope = (u - u_prev) / 1.0
        for j in range(factor + 1):
            x = (i * factor + j) / factor
            if x == i:
                fine[j] = u_prev
            elif x == i + 1.0:
                fine[j] = u
            else:
                fine[j] = slope * (x - i) + u_prev
    else:
        fine[:] = u_prev
    y, v, z = _interval(fine, 0, n_sub, coef[0] / n_sub, state[2], state[3], state[4], coef[3], coef[4], coef[5],
                        coef[6], coef[7], coef[8], coef[9])
    if _capped(y, v, z):
        state[5] = 1.0  # the state before the failure is kept (finite)
        return math.nan
    state[2], state[3], state[4] = y, v, z
    return y


@njit(cache=True, parallel=True)
def oscillator_batch(u_fine, n_sub, dt, P, start, stop):
    """y (B, stop - start) for parameter rows (m, c, k, alpha, beta gamma, beta delta, nu)."""
    out = np.empty((P.shape[0], stop - start))
    for b in prange(P.shape[0]):
        _simulate_one(u_fine, n_sub, dt, P[b, 0], P[b, 1], P[b, 2], P[b, 3], P[b, 4], P[b, 5], P[b, 6],
                      start, stop, out[b])
    return out


class OscillatorStepper(ArrayStepper):
    """The constant-time stepper of ``bouc-wen-oscillator`` with a causal input interpolation
    ("linear", "hold"): state (first, the previous force, y, y', z, failed, k); each step integrates
    one sample interval with the batch kernel's ``_interval`` (``oscillator_advance``)."""

    def __init__(self, model: "BoucWenOscillator", dt: float, params):
        self._setup(model, dt, (("first", 0), ("u1", 0), ("y", 0), ("v", 0), ("z", 0), ("failed", 0), ("k", 0)))
        P = model._check_param_sets(model.pack(params) if isinstance(params, Mapping) else params)
        row = model._kernel_rows(P)[0]
        linear = 1.0 if model.input_interpolation == "linear" else 0.0
        self._c = np.concatenate(([self.dt, float(model.n_substeps), linear], row))
        self._fine = np.empty(2 * model.n_substeps + 1)
        self.reset()

    def _rest(self) -> np.ndarray:
        return np.array([1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])

    def _valid(self, array: np.ndarray) -> bool:
        k = array[6]
        return bool(np.all(np.isfinite(array)) and k >= 0 and k == int(k) and (array[0] == 0.0) != (k == 0))

    def _advance(self, u: float) -> float:
        return oscillator_advance(u, self._state, self._c, self._fine)


def fine_input(u: np.ndarray, factor: int, how: str) -> np.ndarray:
    """The force within each sample interval: shape (n - 1, factor + 1), value j of interval i at
    t_i + j dt / factor (j = factor: the interval's end, as a left limit for ``hold``)."""
    n = u.size
    if how == "hold":
        return np.repeat(u[:-1, None], factor + 1, axis=1)
    if how == "linear":
        grid = np.interp(np.arange((n - 1) * factor + 1) / factor, np.arange(n), u)
    else:
        spec = np.fft.rfft(u)
        if n % 2 == 0 and n > 1:
            spec[-1] *= 0.5  # the Nyquist line splits into +/- frequencies of the finer grid
        padded = np.zeros(n * factor // 2 + 1, dtype=complex)
        padded[:spec.size] = spec
        grid = np.fft.irfft(padded, n * factor)[:(n - 1) * factor + 1] * factor
    idx = np.arange(n - 1)[:, None] * factor + np.arange(factor + 1)[None, :]
    return grid[idx]


class BoucWenOscillator(HysteresisModel):
    """Single-degree-of-freedom oscillator with a Bouc-Wen force; see the module docstring."""

    name = "bouc-wen-oscillator"

    def __init__(self, fixed_nu: float | None = 1.0, beta: float = 1000.0, n_substeps: int = 20,
                 input_interpolation: str = "fourier"):
        name = self.name
        self.fixed_nu = None if fixed_nu is None else check_number(name, "fixed_nu (None: nu identified)",
                                                                    fixed_nu, 1.0, NU_MAX)
        self.beta = check_number(name, "beta", beta, positive=True)
        self.n_substeps = check_int(name, "n_substeps", n_substeps, 1, 1000)
        self.input_interpolation = check_choice(name, "input_interpolation", input_interpolation, INTERPOLATIONS)

    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        stiff = scale.u / scale.y
        t = scale.time
        shape = SHAPE_BOUND / (self.beta * scale.y)
        params = [
            Parameter("m", stiff * t * t / 100.0, 1e-6 * stiff * t * t, 100.0 * stiff * t * t, False, "mass",
                      unit="u*s^2/y"),
            Parameter("c", stiff * t / 100.0, 0.0, 100.0 * stiff * t, False, "viscous damping", unit="u*s/y"),
            Parameter("k", stiff / 2.0, 0.0, STIFFNESS_BOUND * stiff, False, "linear stiffness", unit="u/y"),
            Parameter("alpha", stiff / 2.0, 0.0, STIFFNESS_BOUND * stiff, False, "Bouc-Wen initial stiffness", unit="u/y"),
            Parameter("gamma", 0.0, -shape, shape, False, "Bouc-Wen gamma (at the fixed beta)", unit="1"),
            Parameter("delta", 0.0, -shape, shape, False, "Bouc-Wen delta (at the fixed beta)", unit="1"),
        ]
        if self.fixed_nu is None:
            params.append(Parameter("nu", 1.0, 1.0, NU_MAX, False, "Bouc-Wen exponent nu", unit="1"))
        return params

    @property
    def noncausal_reason(self) -> str | None:
        if self.input_interpolation == "fourier":
            return ("its 'fourier' input interpolation uses the whole record, so the output at a sample depends "
                    "on later inputs (use input_interpolation='linear' or 'hold' for a stepper)")
        return None

    def stepper(self, dt: float, params, input_range=None) -> OscillatorStepper:
        """A constant-time ``OscillatorStepper`` (the batch kernel's RK4 sample interval per step) for
        the causal interpolations; "fourier" refuses (``noncausal_reason``)."""
        self._check_causal()
        return OscillatorStepper(self, dt, params)

    # --- simulation ------------------------------------------------------
    def _fine(self, u: np.ndarray) -> np.ndarray:
        key = (u.size, hash(u.tobytes()))
        cache = self.__dict__.setdefault("_fine_cache", {})
        fine = cache.get(key)
        if fine is None:
            if len(cache) >= 3:  # a long record's grid is large (40 values per sample)
                cache.clear()
            fine = cache[key] = np.ascontiguousarray(fine_input(u, 2 * self.n_substeps, self.input_interpolation).ravel())
        return fine

    def _kernel_rows(self, P: np.ndarray) -> np.ndarray:
        col = {n: P[:, i] for i, n in enumerate(self.param_names)}
        nu = col["nu"] if self.fixed_nu is None else np.full(P.shape[0], float(self.fixed_nu))
        rows = np.stack([col["m"], col["c"], col["k"], col["alpha"], self.beta * col["gamma"],
                         self.beta * col["delta"], nu], axis=1)
        return np.ascontiguousarray(rows)

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        return oscillator_batch(self._fine(u), self.n_substeps, float(dt), self._kernel_rows(P), 0, u.size)

    def simulate_window_batch(self, u, dt: float, param_sets, window, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        start, stop = self._window_bounds(u, window)
        Y = oscillator_batch(self._fine(u), self.n_substeps, float(dt), self._kernel_rows(P), start, stop)
        return np.ascontiguousarray(Y[:, self._in_span(u, window, start)])

    # --- starts -----------------------------------------------------------
    def start_from_data(self, records, scale):
        """``linear_start`` on the longest fit record's window, and ``bounds_around`` it."""
        u, y, dt, window = max(records, key=lambda r: np.size(r[0]))
        start = self.linear_start(u, y, dt, window)
        return start, self.bounds_around(start, scale)

    def linear_start(self, u, y, dt: float, window=slice(None)) -> dict[str, float]:
        """A start point: m, c and k + alpha by linear least squares of u = m y'' + c y' + (k + alpha) y
        over ``window`` (central differences for y', y''), split k = alpha = (k + alpha) / 2, with
        gamma = delta = 0 (no hysteresis: then z = alpha y exactly) and nu = 1."""
        u = self._check_input(u, dt)
        y = np.asarray(y, dtype=float)
        if y.shape != u.shape:
            raise ModelError(f"{self.name}: linear_start needs u and y of the same shape, got {u.shape}, {y.shape}")
        start, stop = self._window_bounds(u, window)
        start, stop = max(start, 1), min(stop, u.size - 1)
        if stop - start < 3:
            raise ModelError(f"{self.name}: linear_start needs at least 3 interior samples in the window")
        s = slice(start, stop)
        vel = (y[start + 1:stop + 1] - y[start - 1:stop - 1]) / (2.0 * dt)
        acc = (y[start + 1:stop + 1] - 2.0 * y[s] + y[start - 1:stop - 1]) / (dt * dt)
        A = np.stack([acc, vel, y[s]], axis=1)
        (m, c, k_total), *_ = np.linalg.lstsq(A, u[s], rcond=None)
        if not (m > 0 and c >= 0 and k_total > 0):
            raise ModelError(f"{self.name}: the linear fit gave non-physical m = {m:.4g}, c = {c:.4g}, "
                             f"k + alpha = {k_total:.4g}; give a start by hand")
        start_point = {"m": float(m), "c": float(c), "k": float(k_total) / 2.0, "alpha": float(k_total) / 2.0,
                       "gamma": 0.0, "delta": 0.0}
        if self.fixed_nu is None:
            start_point["nu"] = 1.0
        return start_point

    def bounds_around(self, start: Mapping[str, float], scale: DataScale, factor: float = 10.0) -> dict:
        """Bounds for ``identify``: m within [start / factor, factor x start]; c, k, alpha within
        [0, factor x start] (k and alpha: of k + alpha; c at least
        of a damping ratio 0.005),
        gamma, delta and nu at their default bounds for ``scale``. Bound widths set lsq's scaling and
        finite-difference steps, so they should match the parameters' magnitudes."""
        if not factor > 1:
            raise ModelError(f"{self.name}: bounds_around needs factor > 1, got {factor!r}")
        defaults = {p.name: (p.min, p.max) for p in self.parameters(scale)}
        k_total = start["k"] + start["alpha"]
        out = {"m": (start["m"] / factor, factor * start["m"]), "c": (0.0, factor * max(start["c"], 0.01 * math.sqrt(start["m"] * k_total))),
               "k": (0.0, factor * k_total), "alpha": (0.0, factor * k_total)}
        for name in ("gamma", "delta", "nu"):
            if name in defaults:
                out[name] = defaults[name]
        return out
