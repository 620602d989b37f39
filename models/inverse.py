"""Causal inverses of the Prandtl-Ishlinskii family (issue 15).

The step structure. Every invertible model here computes its output one sample at a
time from its state after the previous sample (k = 0, 1, ...; u = u(k)):

    a       = |u - u(k-1)| / dt                       (u(-1) = u(-2) = u(0): 0 at k = 0)
    W_i(k)  = play_update(W_i(k-1), u - g_lo a - r_lo_i, u + g_hi a + r_hi_i)     (W_i(-1) = 0)
    x_j(k)  = f_j x_j(k-1) + b0_j u(k-1)^p_j + b1_j u^p_j                        (x_j(0) = 0)
    y(k)    = base(k) + sum_j poly_j u^j + q (u - 2 u(k-1) + u(k-2)) / dt^2
              + sum_i a_i W_i(k) + sum_j c_j x_j(k)

    mrpim / classical-pi   r_lo = r_i, r_hi = 0, g_lo = gamma, g_hi = lambda (0 for classical)
    rate-dependent-pi      r_lo = r_hi = r0_i, g_lo = g_hi = beta
    mrpim+relaxation       first-order-hold low-pass filters x_j (``filter_kernels``)
    mrpim+creep            base(k) = offset + s (1 - exp(-t_k / T_c))

``step_output`` evaluates y(k) and dy/du for a candidate u without touching the
state; ``step_advance`` commits a chosen u. ``step_simulate`` runs the model forward
through them (the tests check it against each model's own forward kernel).

The numerical inverse (``invert_steps``; for the other models their own kernels, all
through one root search, ``search_start`` / ``search_next``): at each sample,
g(u) = y(k; u) - y_d(k) is searched on [u_lo, u_hi] (the input limits, narrowed to
u(k-1) +- max_rate dt when a rate limit is given; u(-1) = ``u_start``, the input the
actuator rests at) by walking outward from the previous input u(k-1) in steps of
(u_hi - u_lo) / n_grid, both ways alternately, up to the first sign change: the root nearest
the previous input, which keeps the input continuous where the model is not monotone in u.
The bracket is refined by Newton steps with the analytic dy/du (secant steps through the
last two evaluations for the models that give no dy/du), falling back to bisection when a
step leaves the bracket or does not halve |g|. Where the walk finds no sign change (y_d beyond the outputs reachable
within the limits, or a flat or non-monotone branch that does not reach it) the inverse takes
the visited point with the smallest |g| (the nearest reachable output on that grid, the
limits and the previous input included) and counts the sample as clipped (Preisach: only
when it misses by more than half its largest stair). A touching root (g >= 0 on both sides)
is counted as clipped too.

The search is reverse-communication (the model's kernel evaluates g where the search asks
and hands it back), so each model keeps its own cached numba kernel and its own step
function, the one its forward simulation runs: ``step_output`` / ``step_advance`` here for
the P-I family, ``branches.branch_step`` (elliptical, dual-polynomial),
``preisach.preisach_step`` (the relay rule ``relay_switch``), ``bouc_wen.bouc_wen_step``.

Where each model is not invertible (the sample is then clipped as above):

* classical-pi: y is piecewise linear and non-decreasing in u when p1 and the partial sums
  of the weights are positive (an increasing loading curve); flat or decreasing pieces
  otherwise, and the output range at a sample is [y(u_lo), y(u_hi)] for a monotone model.
* mrpim: the envelopes make y's slope in u differ on the two sides of u(k-1) by
  -/+ gamma/dt and lambda/dt per active play (x 100 for gamma = 0.1 s at 1 ms), so y is
  generally non-monotone near the previous input; q u'' adds q/dt^2 to the slope (exact
  inverse, but lightly damped internal dynamics: the input rings at about
  sqrt(slope / q) when q > 0, and diverges for q < 0).
* rate-dependent-pi: thresholds grow with |u - u(k-1)|: the same kink at u(k-1).
* mrpim+relaxation / +creep / +interference: as mrpim; the filters add c b1 u^p, the
  creep and the interference only shift the target.
* elliptical, dual-polynomial, preisach, bouc-wen: see each model's ``invert``.
* mrpim+delay, +resonance, +saturation, bouc-wen-oscillator: not inverted here (each says
  why in ``inverse_unavailable``).

Why a rate limit: MRPIM's envelopes move its plays by gamma |u'| (gamma ~ 0.1 s when
fitted on the virtual DEA): an input jump of 1 kV in one 1 ms sample shifts them by
100 kV, a play memory no loop ever visits again, and the model never recovers. A jump
is what an unlimited inverse asks for wherever the root nearest the previous input
disappears. A rate-dependent model is identified only over the input rates of its
records; ``max_rate`` keeps its inverse there (callers state the limit they use).

The analytic inverse of classical P-I (``classical_pi_inverse``) follows Krejci &
Kuhnen, "Inverse control of systems with hysteresis and creep", IEE Proc. Control
Theory Appl. 148 (2001) 185-192, and Kuhnen, "Modeling, identification and
compensation of complex hysteretic nonlinearities: a modified Prandtl-Ishlinskii
approach", Eur. J. Control 9 (2003) 407-418 (cited from memory: the texts could not be
checked from here). For z = a0 u + sum_i a_i P_{h_i}[u] with symmetric plays
P_h[u] = max(u - h, min(u + h, P(k-1))), 0 < h_2 < ... and A_i = a0 + sum_{j<=i} a_j > 0
(the loading curve increases), the inverse is a P-I operator of z:

    u = z / a0 + sum_i b_i P_{s_i}[z],   s_i = a0 h_i + sum_{j<i} a_j (h_i - h_j),
    b_i = -a_i / (A_i A_{i-1}),  initial states q_i = A_i p_i + sum_{j>i} a_j p_j

(p_i the forward plays' initial states). hysbench's one-sided play F_r[u] (band
[u - r, u], from 0) is P_{r/2}[u] - r/2 with initial state r/2, which gives the constants.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .errors import ModelError
from .kernels import play_update

DEFAULT_GRID = 32  # walk step = (u_hi - u_lo) / DEFAULT_GRID
NEWTON_ITERATIONS = 80


@dataclass
class StepStructure:
    """The arrays of the step kernel (see the module docstring); ``base`` has one value per sample."""

    r_lo: np.ndarray
    r_hi: np.ndarray
    g_lo: float
    g_hi: float
    weights: np.ndarray
    poly: np.ndarray
    q: float
    base: np.ndarray
    filter_a: np.ndarray = field(default_factory=lambda: np.zeros(0))
    filter_b0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    filter_b1: np.ndarray = field(default_factory=lambda: np.zeros(0))
    filter_power: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    filter_weight: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def arguments(self) -> tuple:
        c = np.ascontiguousarray
        return (c(self.r_lo, dtype=float), c(self.r_hi, dtype=float), float(self.g_lo), float(self.g_hi),
                c(self.weights, dtype=float), c(self.poly, dtype=float), float(self.q), c(self.filter_a, dtype=float),
                c(self.filter_b0, dtype=float), c(self.filter_b1, dtype=float),
                c(self.filter_power, dtype=np.int64), c(self.filter_weight, dtype=float))


@dataclass
class Inversion:
    """The input a model's inverse computed for a desired output, and where it clipped."""

    u: np.ndarray
    clipped: np.ndarray  # bool per sample: the desired output was not reached
    method: str = "numerical"

    @property
    def n_clipped(self) -> int:
        return int(np.count_nonzero(self.clipped))


# --- the step kernel ----------------------------------------------------------------
@njit(cache=True, fastmath=True, nogil=True)
def step_output(u, first, u1, u2, dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """(y(k), dy/du) for input u at this sample, the state (w, xf, u1 = u(k-1), u2 = u(k-2)) unchanged."""
    if first:
        a = 0.0
        s = 0.0
    else:
        du = u - u1
        a = abs(du) / dt
        s = 1.0 if du > 0 else (-1.0 if du < 0 else 0.0)
    y = base
    dy = 0.0
    for i in range(r_lo.shape[0]):
        lower = u - g_lo * a - r_lo[i]
        upper = u + g_hi * a + r_hi[i]
        v = play_update(w[i], lower, upper)
        y += weights[i] * v
        if v == lower:
            dy += weights[i] * (1.0 - g_lo * s / dt)
        elif v == upper:
            dy += weights[i] * (1.0 + g_hi * s / dt)
    p = 0.0
    dp = 0.0
    for j in range(poly.shape[0] - 1, -1, -1):  # Horner: p = sum_j poly[j] u^(j+1), dp its derivative
        t = p + poly[j]
        dp = dp * u + t
        p = t * u
    y += p
    dy += dp
    if not first:
        y += q * (u - 2.0 * u1 + u2) / (dt * dt)
        dy += q / (dt * dt)
        for j in range(fa.shape[0]):
            pw = fpow[j]
            y += fw[j] * (fa[j] * xf[j] + fb0[j] * u1**pw + fb1[j] * u**pw)
            dy += fw[j] * fb1[j] * pw * u ** (pw - 1)
    return y, dy


@njit(cache=True, fastmath=True, nogil=True)
def step_advance(u, first, u1, dt, w, xf, r_lo, r_hi, g_lo, g_hi, fa, fb0, fb1, fpow):
    """Commit input u: the plays and filters move to sample k (in place)."""
    a = 0.0 if first else abs(u - u1) / dt
    for i in range(r_lo.shape[0]):
        w[i] = play_update(w[i], u - g_lo * a - r_lo[i], u + g_hi * a + r_hi[i])
    for j in range(fa.shape[0]):
        xf[j] = 0.0 if first else fa[j] * xf[j] + fb0[j] * u1 ** fpow[j] + fb1[j] * u ** fpow[j]


@njit(cache=True)
def step_simulate(u, dt, base, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """The model's output for input u, one sample at a time through the step kernel."""
    n = u.shape[0]
    out = np.empty(n)
    w = np.zeros(r_lo.shape[0])
    xf = np.zeros(fa.shape[0])
    u1 = u2 = u[0]
    for k in range(n):
        first = k == 0
        out[k] = step_output(u[k], first, u1, u2, dt, base[k], w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                             fa, fb0, fb1, fpow, fw)[0]
        step_advance(u[k], first, u1, dt, w, xf, r_lo, r_hi, g_lo, g_hi, fa, fb0, fb1, fpow)
        u2 = u[k] if first else u1
        u1 = u[k]
    return out


# --- the root search, one home for every model's inverse ------------------------------
# A reverse-communication search: the model's inversion kernel evaluates g = y(x) - y_d at
# the x the search asks for and hands (g, dy/du) back, until the search is done. So one
# jitted search serves every model's own (cached) kernel without passing functions.
(S_PHASE, S_X, S_RESULT, S_CLIPPED, S_START, S_LO, S_HI, S_H, S_TOL, S_CLIP_TOL, S_BEST_U, S_BEST_G, S_UP_X,
 S_UP_G, S_DN_X, S_DN_G, S_UP_DONE, S_DN_DONE, S_J, S_SIDE, S_XA, S_GA, S_XB, S_GB, S_G_PREV, S_ITER, S_NO_DY, S_XL,
 S_GL) = range(29)
SEARCH_SIZE = 29
PH_START, PH_WALK, PH_REFINE, PH_DONE = 0.0, 1.0, 2.0, 3.0
NO_INPUT = np.zeros(0)  # u_given of a kernel that searches


@njit(cache=True, nogil=True)
def search_start(st, u_given, k, start, limit_lo, limit_hi, max_step, n_grid, tol, clip_tol):
    """Begin the search at sample k around the previous input ``start`` within the limits and
    +- max_step of it (walk step (limit_hi - limit_lo) / n_grid): returns the first x to
    evaluate. ``tol``: |g| that counts as a root; ``clip_tol``: where no sign change is found,
    the sample counts as clipped when the nearest output misses by more. With a non-empty
    ``u_given`` (a kernel run forward) the search is done at once with x = u_given[k]."""
    st[:] = 0.0
    if u_given.shape[0] > 0:
        return _finish(st, u_given[k], False)
    st[S_PHASE] = PH_START
    st[S_START], st[S_H], st[S_TOL], st[S_CLIP_TOL] = start, (limit_hi - limit_lo) / n_grid, tol, clip_tol
    st[S_LO], st[S_HI] = max(limit_lo, start - max_step), min(limit_hi, start + max_step)
    st[S_X] = start
    return start


@njit(cache=True, nogil=True)
def search_done(st):
    return st[S_PHASE] == PH_DONE


@njit(cache=True, nogil=True)
def search_clipped(st):
    return st[S_CLIPPED] != 0.0


@njit(cache=True, nogil=True)
def _finish(st, x, clipped):
    st[S_RESULT] = x
    st[S_CLIPPED] = 1.0 if clipped else 0.0
    st[S_PHASE] = PH_DONE
    st[S_X] = x
    return x


@njit(cache=True, nogil=True)
def _walk_next(st):
    """The next point of the outward walk (up, down, alternately), or the end of the search."""
    while True:
        up_done, dn_done = st[S_UP_DONE] != 0.0, st[S_DN_DONE] != 0.0
        if up_done and dn_done:
            return _finish(st, st[S_BEST_U], st[S_BEST_G] > st[S_CLIP_TOL])
        if st[S_SIDE] >= 2.0:
            st[S_SIDE] = 0.0
            st[S_J] += 1.0
        side = st[S_SIDE]
        if (side == 0.0 and up_done) or (side == 1.0 and dn_done):
            st[S_SIDE] = side + 1.0
            continue
        step = st[S_J] * st[S_H]
        x = min(st[S_START] + step, st[S_HI]) if side == 0.0 else max(st[S_START] - step, st[S_LO])
        st[S_X] = x
        return x


@njit(cache=True, nogil=True)
def search_next(st, g, dy):
    """Hand back g(x) (and dy/du at x; NaN where the model gives none: secant steps) for the x the
    search asked for; returns the next x (the result once ``search_done``)."""
    x = st[S_X]
    tol = st[S_TOL]
    phase = st[S_PHASE]
    if phase == PH_START:
        st[S_NO_DY] = 1.0 if dy != dy else 0.0  # the model gives no dy/du: secant steps
        st[S_BEST_U], st[S_BEST_G] = x, abs(g)
        if abs(g) <= tol:
            return _finish(st, x, False)
        st[S_UP_X], st[S_UP_G], st[S_DN_X], st[S_DN_G] = x, g, x, g
        st[S_UP_DONE] = 1.0 if x >= st[S_HI] else 0.0
        st[S_DN_DONE] = 1.0 if x <= st[S_LO] else 0.0
        st[S_J], st[S_SIDE], st[S_PHASE] = 1.0, 0.0, PH_WALK
        return _walk_next(st)
    if phase == PH_WALK:
        if abs(g) < st[S_BEST_G]:
            st[S_BEST_U], st[S_BEST_G] = x, abs(g)
        up = st[S_SIDE] == 0.0
        px, pg = (st[S_UP_X], st[S_UP_G]) if up else (st[S_DN_X], st[S_DN_G])
        if abs(g) <= tol:
            return _finish(st, x, False)
        if (g > 0) != (pg > 0):  # a bracket: refine from its better end (evaluated again, for dy/du)
            st[S_XA], st[S_GA], st[S_XB], st[S_GB] = px, pg, x, g
            st[S_G_PREV], st[S_ITER], st[S_PHASE] = np.inf, 0.0, PH_REFINE
            if st[S_NO_DY] != 0.0:  # no dy/du to fetch: the first secant step through the bracket at once
                st[S_XL], st[S_GL] = px, pg
                st[S_X] = x - g * (x - px) / (g - pg)
            else:
                st[S_X] = px if abs(pg) < abs(g) else x
            return st[S_X]
        if up:
            st[S_UP_X], st[S_UP_G], st[S_UP_DONE] = x, g, 1.0 if x >= st[S_HI] else 0.0
        else:
            st[S_DN_X], st[S_DN_G], st[S_DN_DONE] = x, g, 1.0 if x <= st[S_LO] else 0.0
        st[S_SIDE] += 1.0
        return _walk_next(st)
    # PH_REFINE: safeguarded Newton (secant without dy/du) on the bracket [xa, xb]: a step is
    # taken when it stays inside the bracket and the previous one at least halved |g|, else bisection
    xa, ga, xb, gb = st[S_XA], st[S_GA], st[S_XB], st[S_GB]
    if abs(g) <= tol:
        return _finish(st, x, False)
    if (g > 0) == (ga > 0):
        xa, ga = x, g
    else:
        xb, gb = x, g
    st[S_XA], st[S_GA], st[S_XB], st[S_GB] = xa, ga, xb, gb
    lo, hi = min(xa, xb), max(xa, xb)
    if hi - lo <= 1e-15 * (abs(lo) + abs(hi) + 1e-300):
        return _finish(st, xa if abs(ga) < abs(gb) else xb, False)
    if dy != dy:  # NaN: secant through the last two evaluations
        xn = x - g * (x - st[S_XL]) / (g - st[S_GL]) if g != st[S_GL] else 0.5 * (lo + hi)
        st[S_XL], st[S_GL] = x, g
    else:
        xn = x - g / dy if dy != 0.0 else 0.5 * (lo + hi)
    x_next = xn if (lo < xn < hi and abs(g) <= 0.5 * st[S_G_PREV]) else 0.5 * (lo + hi)
    st[S_G_PREV] = abs(g)
    st[S_ITER] += 1.0
    if st[S_ITER] >= NEWTON_ITERATIONS:
        return _finish(st, xa if abs(ga) < abs(gb) else xb, False)
    st[S_X] = x_next
    return x_next


@njit(cache=True)
def invert_steps(yd, dt, base, u_limit_lo, u_limit_hi, u_start, max_step, n_grid, tol, r_lo, r_hi, g_lo, g_hi,
                 weights, poly, q, fa, fb0, fb1, fpow, fw):
    """The causal numerical inverse (module docstring): (u, clipped) for desired outputs yd.
    ``max_step``: the largest input change per sample (inf: none)."""
    n = yd.shape[0]
    u_out = np.empty(n)
    clipped = np.zeros(n, dtype=np.bool_)
    w = np.zeros(r_lo.shape[0])
    xf = np.zeros(fa.shape[0])
    st = np.empty(SEARCH_SIZE)
    u1 = u2 = min(max(u_start, u_limit_lo), u_limit_hi)
    for k in range(n):
        first = k == 0
        x = search_start(st, NO_INPUT, k, u1, u_limit_lo, u_limit_hi, max_step, n_grid, tol, tol)
        while not search_done(st):
            y, dy = step_output(x, first, u1, u2, dt, base[k], w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                                fa, fb0, fb1, fpow, fw)
            x = search_next(st, y - yd[k], dy)
        u_out[k] = x
        clipped[k] = search_clipped(st)
        step_advance(x, first, u1, dt, w, xf, r_lo, r_hi, g_lo, g_hi, fa, fb0, fb1, fpow)
        u2 = x if first else u1
        u1 = x
    return u_out, clipped


# --- the model-facing side ----------------------------------------------------------
class StepInvertible:
    """Mixin for a model that can state its one-sample structure (``step_structure``):
    it gains ``invert`` (the causal numerical inverse) and ``simulate_steps``."""

    def step_structure(self, dt: float, params, input_range, n_samples: int) -> StepStructure:
        raise NotImplementedError

    @property
    def inverse_unavailable(self) -> str | None:
        derivative = getattr(self, "derivative", "backward")
        if derivative != "backward":
            return (f"its {derivative!r} derivative uses later samples, so the output at a sample is not a "
                    "function of the inputs up to it (use derivative='backward')")
        return None

    def _structure(self, dt, params, input_range, n_samples) -> StepStructure:
        reason = self.inverse_unavailable
        if reason:
            raise ModelError(f"model {self.name!r} cannot be inverted: {reason}")
        if input_range is None:
            raise ModelError(f"{self.name}: a step structure needs the input range that fixes the operators "
                             "(the fit's input_range)")
        vec = self.pack(params) if isinstance(params, dict) else np.asarray(params, dtype=float)
        return self.step_structure(float(dt), self.unpack(vec), tuple(map(float, input_range)), int(n_samples))

    def simulate_steps(self, u, dt: float, params, input_range=None) -> np.ndarray:
        """The forward model through the step kernel (equals ``simulate`` up to rounding)."""
        u = self._check_input(u, dt)
        s = self._structure(dt, params, input_range if input_range is not None else (u.min(), u.max()), u.size)
        r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw = s.arguments()
        return step_simulate(u, float(dt), np.ascontiguousarray(s.base), r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                             fa, fb0, fb1, fpow, fw)

    def invert(self, y_desired, dt: float, params, input_range=None, input_limits=None,
               n_grid: int = DEFAULT_GRID, max_rate: float | None = None, u_start: float | None = None) -> Inversion:
        """The causal numerical inverse: the input within ``input_limits`` (default: ``input_range``)
        that makes the model output ``y_desired``, sample by sample (module docstring).
        ``max_rate``: largest |du/dt| (input units per second; None: none); ``u_start``: the
        input before the first sample (default: the lower limit, an actuator at rest)."""
        a = InverseArguments.check(self.name, y_desired, dt, input_range, input_limits, n_grid, max_rate, u_start)
        s = self._structure(dt, params, a.input_range, a.yd.size)
        r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw = s.arguments()
        u, clipped = invert_steps(a.yd, float(dt), np.ascontiguousarray(s.base), a.lo, a.hi, a.u_start, a.max_step,
                                  a.n_grid, a.tol, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw)
        return Inversion(u, clipped)


@dataclass(frozen=True)
class InverseArguments:
    """The checked arguments every model's ``invert`` shares (see ``StepInvertible.invert``)."""

    yd: np.ndarray
    input_range: tuple | None
    lo: float
    hi: float
    u_start: float
    max_step: float  # largest input change per sample (inf: none)
    n_grid: int
    tol: float  # |y - y_d| that counts as reached

    @classmethod
    def check(cls, name, y_desired, dt, input_range, input_limits, n_grid, max_rate, u_start) -> "InverseArguments":
        yd = np.ascontiguousarray(y_desired, dtype=float)
        if yd.ndim != 1 or yd.size == 0 or not np.all(np.isfinite(yd)):
            raise ModelError(f"{name}: the desired output must be a non-empty, finite 1-D array")
        input_range = input_range if input_range is not None else input_limits
        input_limits = input_limits if input_limits is not None else input_range
        if input_limits is None:
            raise ModelError(f"{name}: invert needs input_range (the fit's) or input_limits")
        lo, hi = map(float, input_limits)
        if not (np.isfinite(lo) and np.isfinite(hi) and hi > lo):
            raise ModelError(f"{name}: input limits must have low < high, got {input_limits!r}")
        if not (isinstance(n_grid, (int, np.integer)) and n_grid >= 2):
            raise ModelError(f"{name}: n_grid must be an integer >= 2, got {n_grid!r}")
        if max_rate is not None and not max_rate > 0:
            raise ModelError(f"{name}: max_rate must be positive, got {max_rate!r}")
        max_step = np.inf if max_rate is None else float(max_rate) * float(dt)
        start = lo if u_start is None else float(u_start)
        return cls(yd, tuple(map(float, input_range)), lo, hi, min(max(start, lo), hi), max_step, int(n_grid),
                   1e-12 * (1.0 + float(np.max(np.abs(yd)))))


class KernelInvertible:
    """Mixin for a model inverted through its own step kernel (elliptical, dual-polynomial,
    preisach, bouc-wen): ``step_kernel(yd, u_given, *step_arguments, u_lo, u_hi, u_start,
    max_step, n_grid, tol, clip_tol) -> (u, clipped, y)`` searches the input for yd with
    ``search_next`` or, given a non-empty u_given, runs the model forward through the same steps."""

    inverse_unavailable = None
    step_kernel = None  # the model's jitted kernel (a staticmethod)

    def step_arguments(self, vector: np.ndarray, input_range: tuple) -> tuple:
        """The kernel's model arguments for a parameter vector and the operators' input range."""
        raise NotImplementedError

    def clip_tolerance(self, vector: np.ndarray, input_range: tuple, tol: float) -> float:
        """How far the nearest output may miss y_d before the sample counts as clipped."""
        return tol

    def _step_setup(self, params, input_range) -> tuple:
        vec = self.pack(params) if isinstance(params, dict) else np.asarray(params, dtype=float)
        if vec.shape != (self.n_params,):
            raise ModelError(f"model {self.name!r} takes {self.n_params} parameters, got shape {vec.shape}")
        lo, hi = map(float, input_range)
        if not hi > lo:
            raise ModelError(f"model {self.name!r} needs an input_range of positive width, got ({lo!r}, {hi!r})")
        return vec, (lo, hi)

    def simulate_steps(self, u, dt: float, params, input_range=None) -> np.ndarray:
        """The forward model through the inverse's step kernel (equals ``simulate``)."""
        u = self._check_input(u, dt)
        vec, rng = self._step_setup(params, self._input_range(u, input_range))
        return self.step_kernel(np.zeros(0), u, *self.step_arguments(vec, rng), rng[0], rng[1], u[0], np.inf, 2, 0.0,
                                0.0)[2]

    def invert(self, y_desired, dt: float, params, input_range=None, input_limits=None,
               n_grid: int = DEFAULT_GRID, max_rate: float | None = None, u_start: float | None = None) -> Inversion:
        """The causal numerical inverse (arguments as ``StepInvertible.invert``), searched
        derivative-free; each model's docstring says where it is not invertible."""
        a = InverseArguments.check(self.name, y_desired, dt, input_range, input_limits, n_grid, max_rate, u_start)
        vec, rng = self._step_setup(params, a.input_range)
        u, clipped, _ = self.step_kernel(a.yd, np.zeros(0), *self.step_arguments(vec, rng), a.lo, a.hi, a.u_start,
                                         a.max_step, a.n_grid, a.tol, self.clip_tolerance(vec, rng, a.tol))
        return Inversion(u, clipped)


# --- the analytic inverse of classical P-I -------------------------------------------
@njit(cache=True)
def _pi_operator(z, b0, b, s, q0):
    """u = b0 z + sum_i b_i P_{s_i}[z] with symmetric plays from states q0."""
    n = z.shape[0]
    out = np.empty(n)
    q = q0.copy()
    for k in range(n):
        zk = z[k]
        acc = b0 * zk
        for i in range(s.shape[0]):
            q[i] = play_update(q[i], zk - s[i], zk + s[i])
            acc += b[i] * q[i]
        out[k] = acc
    return out


def classical_pi_inverse(z, a0: float, weights: np.ndarray, half_thresholds: np.ndarray,
                         initial_states: np.ndarray) -> np.ndarray:
    """u with a0 u + sum_i weights_i P_{h_i}[u] = z (symmetric plays, thresholds h_i > 0 increasing,
    plays starting from ``initial_states``); see the module docstring. Raises ModelError where the
    loading curve does not increase (no P-I inverse exists)."""
    a = np.asarray(weights, dtype=float)
    h = np.asarray(half_thresholds, dtype=float)
    p = np.asarray(initial_states, dtype=float)
    cumulative = a0 + np.cumsum(a)  # A_i
    if not (a0 > 0 and np.all(cumulative > 0)):
        raise ModelError("classical P-I: no analytic inverse: the loading curve is not increasing "
                         f"(a0 = {a0:.4g}, partial sums min {float(np.min(cumulative, initial=a0)):.4g}); "
                         "use the numerical inverse, which clips where the model cannot be inverted")
    if np.any(np.diff(h) <= 0) or (h.size and h[0] <= 0):
        raise ModelError("classical P-I: the analytic inverse needs strictly increasing positive thresholds")
    previous = np.concatenate(([a0], cumulative[:-1]))  # A_{i-1}
    s = np.array([a0 * h[i] + float(np.sum(a[:i] * (h[i] - h[:i]))) for i in range(h.size)])
    b = -a / (cumulative * previous)
    tail = np.concatenate((np.cumsum((a * p)[::-1])[::-1][1:], [0.0]))  # sum_{j>i} a_j p_j
    q0 = cumulative * p + tail
    return _pi_operator(np.ascontiguousarray(z, dtype=float), 1.0 / a0, b, s, q0)
