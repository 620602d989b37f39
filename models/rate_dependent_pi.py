"""Rate-dependent Prandtl-Ishlinskii model with rate-dependent thresholds
(registry name ``rate-dependent-pi``).

Form followed: the rate-dependent P-I of Al Janaideh, Rakheja & Su,
"Development of the rate-dependent Prandtl-Ishlinskii model for smart
actuators", Smart Mater. Struct. 17 (2008) 035026, in the form with
thresholds r_j(t) = alpha j + beta |du/dt| used by Al Janaideh & Krejci,
"Inverse rate-dependent Prandtl-Ishlinskii model for feedforward
compensation of hysteresis in a piezomicropositioning actuator", IEEE/ASME
Trans. Mechatronics 18 (2013) 1498-1507 (cited from memory: the papers'
text could not be checked from here; see also Al Janaideh, Krejci &
Monteiro, "Inverse rate-dependent Prandtl-Ishlinskii operators and
applications", Appl. Math. (2023), on play operators whose thresholds are
functions of time). Symmetric play operators whose thresholds grow with the
input rate, discretised:

    y(k)   = c + sum_{j=1..K} p_j u(k)^j + sum_{i=1..N} a_i W_i(k)
    W_i(k) = max(u(k) - r_i(k), min(u(k) + r_i(k), W_i(k-1))),   W_i(-1) = 0
    r_i(k) = r0_i + beta |u'(k)|,   r0_i = (i - 1)/N * (u_max - u_min)/2

Interpretations: the thresholds' rate-independent part is spread over
[0, half the input range) of ``input_range`` (None: the input's own range):
a symmetric play of threshold >= half the span no longer moves in a periodic
regime, so larger thresholds would only duplicate the offset. The weights
a_i are free constants (the discretised density, as in the seed paper's
eq. 8) rather than a parametric density evaluated at the moving thresholds
(that line of work uses an exponential one), so the model is linear in a_i, p_j and
c given beta, the only nonlinear parameter (in seconds, >= 0: thresholds
grow with the rate). u' is the backward difference [u(k) - u(k-1)]/T with
u(-1) = u(0), as the seed paper estimates it (``derivative="smoothed"``
for noisy inputs, see ``derivatives``); W_i(-1) = 0 is the classical zero
initial state, as for ``classical-pi``. ``poly_order`` K = 1 is the
published p u; more terms give an asymmetric loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .base import DataScale, HysteresisModel, Parameter
from .derivatives import DERIVATIVE_METHODS, derivatives
from .errors import ModelError
from .hyperparameters import MAX_OPERATORS, check_bool, check_choice, check_int, check_number
from .inverse import StepStructure
from .pi_stepper import SteppableStructure
from .kernels import KERNEL_FASTMATH, play_update

POLY_BOUND = 5.0  # |p_j| <= POLY_BOUND * y / u**j
WEIGHT_BOUND = 20.0  # |a_i| <= WEIGHT_BOUND * y / u
BETA_BOUND = 0.5  # 0 <= beta <= BETA_BOUND * time (s)


@njit(cache=True)
def rd_play_operators(u, abs_du, r0, beta, w0):
    """Outputs (T, N) of the N symmetric plays with thresholds r0_i + beta |u'|."""
    out = np.empty((u.shape[0], r0.shape[0]))
    _rd_play_window(u, abs_du, r0, beta, w0, 0, u.shape[0], out)  # the window kernel from sample 0
    return out


@njit(cache=True, nogil=True)
def _rd_play_window(u, abs_du, r0, beta, w0, start, stop, out):
    """Plays run from sample 0; rows [start, stop) written to out (stop - start, N)."""
    n_op = r0.shape[0]
    w = np.empty(n_op)
    for i in range(n_op):
        w[i] = w0
    for k in range(stop):
        uk = u[k]
        extra = beta * abs_du[k]
        for i in range(n_op):
            r = r0[i] + extra
            w[i] = play_update(w[i], uk - r, uk + r)
        if k >= start:
            for i in range(n_op):
                out[k - start, i] = w[i]


@njit(cache=True, nogil=True)
def rd_play_window(u, abs_du, r0, beta, w0, start, stop):
    """``rd_play_window_batch`` for one beta, without threads: (stop - start, N)."""
    out = np.empty((stop - start, r0.shape[0]))
    _rd_play_window(u, abs_du, r0, beta, w0, start, stop, out)
    return out


@njit(cache=True, parallel=True)
def rd_play_window_batch(u, abs_du, r0, betas, w0, start, stop):
    """Play outputs on rows [start, stop) for many betas, in parallel: (B, stop - start, N)."""
    out = np.empty((betas.shape[0], stop - start, r0.shape[0]))
    for b in prange(betas.shape[0]):
        _rd_play_window(u, abs_du, r0, betas[b], w0, start, stop, out[b])
    return out


@njit(cache=True, fastmath=KERNEL_FASTMATH, nogil=True)
def _rd_pi_output(u, abs_du, r0, beta, weights, poly, offset, w0, out):
    """out[k] = offset + sum_j poly[j-1] u^j + sum_i weights[i] W_i(k), one parameter set."""
    n_op = r0.shape[0]
    n_poly = poly.shape[0]
    w = np.empty(n_op)
    for i in range(n_op):
        w[i] = w0
    for k in range(u.shape[0]):
        uk = u[k]
        extra = beta * abs_du[k]
        acc = 0.0
        for i in range(n_op):
            r = r0[i] + extra
            v = play_update(w[i], uk - r, uk + r)
            w[i] = v
            acc += weights[i] * v
        p = 0.0
        for j in range(n_poly - 1, -1, -1):
            p = (p + poly[j]) * uk
        out[k] = offset + p + acc


@njit(cache=True, nogil=True)
def rd_pi_output(u, abs_du, r0, beta, weights, poly, offset, w0):
    out = np.empty(u.shape[0])
    _rd_pi_output(u, abs_du, r0, beta, weights, poly, offset, w0, out)
    return out


@njit(cache=True, parallel=True)
def rd_pi_batch(u, abs_du, r0, betas, weights, polys, offsets, w0):
    """y (B, T) for many parameter sets, in parallel over sets."""
    n_set = betas.shape[0]
    out = np.empty((n_set, u.shape[0]))
    for b in prange(n_set):
        _rd_pi_output(u, abs_du, r0, betas[b], weights[b], polys[b], offsets[b], w0, out[b])
    return out


class RateDependentPI(SteppableStructure, HysteresisModel):
    """P-I with thresholds growing with |du/dt|; see the module docstring."""

    name = "rate-dependent-pi"

    def __init__(
        self,
        n_operators: int = 10,
        poly_order: int = 1,
        offset: bool = True,
        derivative: str = "backward",
        derivative_window: float = 0.05,
    ):
        name = self.name
        self.n_operators = check_int(name, "n_operators", n_operators, 1, MAX_OPERATORS)
        self.poly_order = check_int(name, "poly_order", poly_order, 0, 12)
        self.offset = check_bool(name, "offset", offset)
        self.derivative = check_choice(name, "derivative", derivative, DERIVATIVE_METHODS)
        self.derivative_window = check_number(name, "derivative_window", derivative_window, positive=True)

    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        u, y, T = scale.u, scale.y, scale.time
        params = [Parameter("beta", 0.0, 0.0, BETA_BOUND * T, False,
                            "threshold growth with the input rate: r_i = r0_i + beta |u'| (s)", unit="s")]
        for j in range(1, self.poly_order + 1):
            b = POLY_BOUND * y / u**j
            params.append(Parameter(f"p{j}", 0.0, -b, b, True, f"polynomial coefficient of u^{j}", unit=f"y/u^{j}"))
        for i in range(1, self.n_operators + 1):
            b = WEIGHT_BOUND * y / u
            params.append(Parameter(f"a{i}", 0.0, -b, b, True, f"weight of play operator {i}", unit="y/u"))
        if self.offset:
            params.append(self.offset_parameter(scale))
        return params

    def step_structure(self, dt: float, params, input_range, n_samples: int) -> StepStructure:
        """The step kernel's arrays (models/inverse.py): symmetric plays r0_i + beta |u'|."""
        r0 = self.base_thresholds(np.zeros(1), input_range)
        return StepStructure(
            r_lo=r0, r_hi=r0, g_lo=params["beta"], g_hi=params["beta"],
            weights=np.array([params[f"a{i}"] for i in range(1, self.n_operators + 1)]),
            poly=np.array([params[f"p{j}"] for j in range(1, self.poly_order + 1)]), q=0.0,
            base=np.full(n_samples, params["offset"] if self.offset else 0.0))

    def base_thresholds(self, u, input_range=None) -> np.ndarray:
        """r0_i = (i - 1)/N * (u_max - u_min)/2."""
        lo, hi = self._input_range(np.asarray(u, dtype=float), input_range)
        return np.arange(self.n_operators, dtype=float) / self.n_operators * 0.5 * max(hi - lo, 0.0)

    def abs_rate(self, u, dt: float) -> np.ndarray:
        du, _ = derivatives(u, dt, self.derivative, self.derivative_window)
        return np.ascontiguousarray(np.abs(du))

    def play_outputs(self, u, dt: float, beta: float, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        return rd_play_operators(u, self.abs_rate(u, dt), self.base_thresholds(u, input_range), float(beta), 0.0)

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        names = self.param_names
        index = {n: i for i, n in enumerate(names)}
        betas = np.ascontiguousarray(P[:, index["beta"]])
        polys = np.ascontiguousarray(P[:, [index[f"p{j}"] for j in range(1, self.poly_order + 1)]])
        weights = np.ascontiguousarray(P[:, [index[f"a{i}"] for i in range(1, self.n_operators + 1)]])
        offsets = np.ascontiguousarray(P[:, index["offset"]]) if self.offset else np.zeros(P.shape[0])
        abs_du, r0 = self.abs_rate(u, dt), self.base_thresholds(u, input_range)
        if P.shape[0] == 1:
            return rd_pi_output(u, abs_du, r0, betas[0], weights[0], polys[0], offsets[0], 0.0)[None, :]
        return rd_pi_batch(u, abs_du, r0, betas, weights, polys, offsets, 0.0)

    def regressors(self, u, dt: float, nonlinear, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        nonlinear = dict(nonlinear or {})
        if set(nonlinear) != {"beta"}:
            raise ModelError(f"{self.name}: regressors need exactly the nonlinear parameters ['beta'], "
                             f"got {sorted(nonlinear)}")
        F = self.play_outputs(u, dt, nonlinear["beta"], input_range)
        cols = [u**j for j in range(1, self.poly_order + 1)] + [F[:, i] for i in range(self.n_operators)]
        if self.offset:
            cols.append(np.ones_like(u))
        return np.stack(cols, axis=1)

    def windowed_regressors_batch(self, u, dt: float, nonlinear_sets, window, input_range=None) -> np.ndarray:
        """Rows ``window`` of ``regressors`` for many betas (n_sets, 1): (n_sets, n_rows, n_linear)."""
        u = self._check_input(u, dt)
        sets = np.asarray(nonlinear_sets, dtype=float).reshape(-1, 1)
        start, stop = self._window_bounds(u, window)
        abs_du, r0 = self.abs_rate(u, dt), self.base_thresholds(u, input_range)
        if sets.shape[0] == 1:
            F = rd_play_window(u, abs_du, r0, float(sets[0, 0]), 0.0, start, stop)[None]
        else:
            F = rd_play_window_batch(u, abs_du, r0, np.ascontiguousarray(sets[:, 0]), 0.0, start, stop)
        pick = self._in_span(u, window, start)
        F = F[:, pick]
        uw = u[start:stop][pick]
        n_set, n_rows = sets.shape[0], uw.size
        out = np.empty((n_set, n_rows, len(self.linear_names)))
        for j in range(1, self.poly_order + 1):
            out[:, :, j - 1] = uw**j
        out[:, :, self.poly_order:self.poly_order + self.n_operators] = F
        if self.offset:
            out[:, :, -1] = 1.0
        return out
