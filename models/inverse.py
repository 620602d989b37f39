"""Causal inverses of the Prandtl-Ishlinskii family.

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
state; ``step_commit`` commits a chosen u (``guided_output`` does both for the reference-driven
inverse, below). Both are ``kernels.pi_sample``, the per-sample
update the batch kernel (``kernels._pi_output_window``), the steppers (``pi_stepper``) and the
exported C share. ``step_simulate`` runs the model forward through them (the tests check it
against each model's own forward kernel).

The numerical inverse (``invert_steps``; for the other models their own kernels, all
through one root search, ``root_search.search_start`` / ``search_next``): at each sample,
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
function, the one its forward simulation runs: ``step_output`` / ``step_commit`` here for
the P-I family, ``branches.branch_step`` (elliptical, dual-polynomial),
``preisach.preisach_step`` (the relay rule ``relay_switch``), ``bouc_wen.bouc_wen_step``.

Where each model is not invertible (the sample is then clipped as above):

* classical-pi: y is piecewise linear and non-decreasing in u when p1 and the partial sums
  of the weights are positive (an increasing loading curve); flat or decreasing pieces
  otherwise, and the output range at a sample is [y(u_lo), y(u_hi)] for a monotone model.
* mrpim: the envelopes make y's slope in u differ on the two sides of u(k-1) by
  -/+ gamma/dt and lambda/dt per active play (x 100 for gamma = 0.1 s at 1 ms), so y is
  generally non-monotone near the previous input; q u'' adds q/dt^2 to the slope. The
  inverse is exact but need not be stable (below).
* rate-dependent-pi: thresholds grow with |u - u(k-1)|: the same kink at u(k-1).
* mrpim+relaxation / +creep / +interference: as mrpim; the filters add c b1 u^p, the
  creep and the interference only shift the target.
* elliptical, dual-polynomial, preisach, bouc-wen (``KernelInvertible``): see each model's
  module docstring (branches.py for the two branch models).
* mrpim+delay, +resonance, +saturation, bouc-wen-oscillator: not inverted here (each says
  why in ``inverse_unavailable``).

Why the exact inverse diverges. With the play and filter states held, y(k) depends on u(k),
u(k-1) (the envelopes' rate term, the first difference of q u'') and u(k-2) (q u''); an
error e in the inverse's input therefore obeys c0 e(k) + c1 e(k-1) + c2 e(k-2) = 0 with
c_j = dy(k)/du(k-j). Where a root of c0 z^2 + c1 z + c2 lies outside the unit circle (a zero
of the model outside it) the recursion amplifies any error, rounding included, by that modulus
per sample; no causal exact inverse is then stable. ``recursion_radius`` gives the largest
modulus per sample (MRPIM fitted on the virtual DEA: up to 1.008 on the protocol's sines, above 1 on
50-75 % of the samples, with the envelopes the cause; docs/deploying.md); the export's inverse check
reports it. varpro's ``stable_inverse`` identifies under the conditions that keep it within a radius.

The reference-driven inverse (``inverse="reference-driven"``; ``"auto"`` picks it for a model with
rate or relaxation terms, the exact one otherwise, where the two coincide). The literature's
feedforward for rate-dependent P-I models (Al Janaideh et al.) takes the rate from the
reference, not from the input being solved for. Here: the reference is mapped to input units,
m(k) = u_start + (y_d(k) - y_d(0)) / G, G the model's quasi-static gain (``guide_gain``: the
secant of its first loading curve over the input range, rate terms off, filters at steady
state); the guide g follows m through a critically damped second-order follower of time
constant ``guide_time`` (default ``DEFAULT_GUIDE_TIME``; 0: g = m), its step limited by the rate
limit (``guide_step``). Each sample then solves, for u alone (``guided_output``):

    y(k) = base(k) + sum_j poly_j u^j + q g''(k) + sum_i a_i W_i(k)
           + sum_j c_j (x_j(k) - g(k)^p_j + u^p_j),        x_j driven by g
    W_i(k) = play_update(W_i(k-1), u - g_lo |g'| - r_lo_i, u + g_hi |g'| + r_hi_i)

(g', g'' backward differences of the guide). With g = u it is the model (tested); with g given
it has no recursion through u's differences, so its error does not grow through them (c1 = c2 =
0); the memory left is the plays' (a P-I operator's) and the root search's choice of branch. It
is the exact inverse of this reference-driven model, not of the model: a reachable trajectory's
input comes back only as far as the guide matches it (on the DEA's fits, 0.1-0.5 kV where the
rate-free loading falls after a reversal). It inherits two weaknesses: a reference with sharp
features asks the rate terms for rates no input has (the follower and ``max_rate`` bound them),
and where the rate-free part's slope after a reversal is negative (a1 < 0 with a small
polynomial slope: a1 + p'(u) < 0 below 0.82 kV for Table 2's MRPIM, a1 = -4.37, and below
0.65 kV for the DEA's varpro fit, a1 = -1.32) the per-sample equation has
no root near the previous input and the inverse clips or jumps (``export_c.check_inverse``
measures it as ringing). docs/deploying.md has the measurements.

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

(p_i the forward plays' initial states, a memory some input history leaves: |p_{i+1} - p_i| <=
h_{i+1} - h_i; from other states these q_i do not reproduce the input). hysbench's one-sided
play F_r[u] (band [u - r, u], from 0) is P_{r/2}[u] - r/2 with initial state r/2, which gives
the constants.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from .errors import ModelError
from .hyperparameters import check_int, check_number
from .kernels import KERNEL_FASTMATH, backward_rates, pi_sample, play_update
from .stepper import ArrayInverseStepper, InverseStepper, check_state_keys, check_step_input
from .root_search import NO_INPUT, SEARCH_SIZE, search_clipped, search_done, search_next, search_start

DEFAULT_GRID = 32  # walk step = (u_hi - u_lo) / DEFAULT_GRID
#: the P-I family's causal inverses (``StepInvertible.invert``'s ``inverse``); "auto" picks
#: "reference-driven" for a model with rate or relaxation terms, else "exact" (the two are then equal)
INVERSES = ("auto", "exact", "reference-driven")
#: the reference-driven inverse's guide follower time constant (s) unless given (docs/deploying.md
#: has the measurement behind it: shorter lets the inverse of a fitted MRPIM ring on its own sines)
DEFAULT_GUIDE_TIME = 0.02


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
    """The input a model's inverse computed for a desired output, and where it clipped.

    Attributes
    ----------
    u : numpy.ndarray
        The input, one value per sample of the desired output, input unit.
    clipped : numpy.ndarray
        Bool per sample: the desired output was not reached (the input at a limit).
    method : str
        How the inverse was computed: "numerical" (a root search, sample by sample) or "analytic" (a
        closed form: classical-pi's play inversion).
    inverse : str
        Which causal inverse ran (P-I family): "exact" or "reference-driven" (``INVERSES``).
    exact_recursion_radius : float
        The largest root modulus of the exact inverse's error recursion along the returned input
        (``recursion_radius``; above 1 the exact inverse is unstable there); NaN where not computed.
    n_clipped : int
        The number of clipped samples (a property).
    """

    u: np.ndarray
    clipped: np.ndarray
    method: str = "numerical"
    inverse: str = "exact"
    exact_recursion_radius: float = float("nan")

    @property
    def n_clipped(self) -> int:
        """The number of clipped samples."""
        return int(np.count_nonzero(self.clipped))


# --- the step kernel ----------------------------------------------------------------
@njit(inline="always", fastmath=KERNEL_FASTMATH)
def step_output(u, first, u1, u2, dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """(y(k), dy/du) for input u at this sample, the state (w, xf, u1 = u(k-1), u2 = u(k-2)) unchanged."""
    inv_dt = 1.0 / dt
    a, s, d2 = backward_rates(u, u1, u2, first, inv_dt, inv_dt * inv_dt)
    return pi_sample(u, a, s, d2, first, u1, inv_dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                     fa, fb0, fb1, fpow, fw, False, True)


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def step_commit(u, first, u1, u2, dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """Commit input u: the plays and filters move to sample k (in place); returns y(k)."""
    inv_dt = 1.0 / dt
    a, s, d2 = backward_rates(u, u1, u2, first, inv_dt, inv_dt * inv_dt)
    return pi_sample(u, a, s, d2, first, u1, inv_dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                     fa, fb0, fb1, fpow, fw, True, False)[0]


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def step_simulate(u, dt, base, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """The model's output for input u, one sample at a time through the step kernel."""
    n = u.shape[0]
    out = np.empty(n)
    w = np.zeros(r_lo.shape[0])
    xf = np.zeros(fa.shape[0])
    u1 = u2 = u[0]
    for k in range(n):
        out[k] = step_commit(u[k], k == 0, u1, u2, dt, base[k], w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                             fa, fb0, fb1, fpow, fw)
        u2 = u1
        u1 = u[k]
    return out


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def invert_sample(yd, first, u1, u2, dt, base, u_limit_lo, u_limit_hi, max_step, n_grid, tol, st, w, xf, r_lo, r_hi,
                  g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """One sample of the causal inverse: the input x for desired output yd (the state, as after the
    previous sample, is committed to x); whether it clipped is ``search_clipped(st)``."""
    x = search_start(st, NO_INPUT, 0, u1, u_limit_lo, u_limit_hi, max_step, n_grid, tol, tol)
    while not search_done(st):
        y, dy = step_output(x, first, u1, u2, dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                            fa, fb0, fb1, fpow, fw)
        x = search_next(st, y - yd, dy)
    step_commit(x, first, u1, u2, dt, base, w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw)
    return x


@njit(cache=True, fastmath=KERNEL_FASTMATH)
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
        x = invert_sample(yd[k], first, u1, u2, dt, base[k], u_limit_lo, u_limit_hi, max_step, n_grid, tol, st, w,
                          xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw)
        u_out[k] = x
        clipped[k] = search_clipped(st)
        u2 = x if first else u1
        u1 = x
    return u_out, clipped


# --- the reference-driven inverse ------------------------------------------------------
@njit(inline="always", fastmath=KERNEL_FASTMATH)
def guided_output(u, first, g, g1, g2, dt, base, w, xg, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow,
                  fw, commit):
    """(y(k), dy/du) of the reference-driven model (module docstring, "The reference-driven inverse")
    for input u: the rates |u'|, u'' are the guide's (g = g(k), g1, g2 the two before), the filters
    follow the guide and add their lag, x_j - g^p_j, to u^p_j. The plays (w) and the guide's filters
    (xg) move to sample k only when ``commit``; dy/du has no rate or lag term (the guide does not
    depend on u)."""
    inv_dt = 1.0 / dt
    a, s, d2 = backward_rates(g, g1, g2, first, inv_dt, inv_dt * inv_dt)
    # s = 0, inv_dt = 0 in the slope: the rates do not move with u
    y, dy = pi_sample(u, a, 0.0, d2, first, g1, 0.0, base, w, xg, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                      fa[:0], fb0[:0], fb1[:0], fpow[:0], fw[:0], commit, not commit)
    for j in range(fa.shape[0]):
        x = 0.0
        if not first:
            pw = fpow[j]
            x = fa[j] * xg[j] + fb0[j] * g1**pw + fb1[j] * g**pw
            y += fw[j] * (x - g**pw + u**pw)
            dy += fw[j] * pw * u ** (pw - 1)
        if commit:
            xg[j] = x
    return y, dy


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def guide_step(mapped, g1, g2, max_step, c):
    """The guide at this sample from the mapped reference (``mapped_reference``) and the guide's two
    previous values: a critically damped second-order follower, c = dt / guide_time per sample
    (c >= 1: the mapped reference itself), its step limited to ``max_step`` (the input's rate limit).
    The follower keeps the reference's sharp features (a corner, a jump, the model's own
    acceleration term) from becoming input rates and accelerations no input has."""
    if c >= 1.0:
        return g1 + min(max(mapped - g1, -max_step), max_step)
    v = (g1 - g2) * (1.0 - 2.0 * c) + c * c * (mapped - g1)
    return g1 + min(max(v, -max_step), max_step)


def guide_rate(dt: float, guide_time: float) -> float:
    """The follower's c per sample for a guide time constant (s); 0: no follower (c = 1)."""
    return 1.0 if guide_time == 0.0 else min(1.0, float(dt) / guide_time)


@njit(inline="always", fastmath=KERNEL_FASTMATH)
def guided_invert_sample(yd, g, first, u1, g1, g2, dt, base, u_limit_lo, u_limit_hi, max_step, n_grid, tol, st, w, xg,
                         r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """One sample of the reference-driven inverse: the input x that makes ``guided_output`` equal yd
    (the same root search as ``invert_sample``, around the previous input u1); the plays and the
    guide's filters are committed to x."""
    x = search_start(st, NO_INPUT, 0, u1, u_limit_lo, u_limit_hi, max_step, n_grid, tol, tol)
    while not search_done(st):
        y, dy = guided_output(x, first, g, g1, g2, dt, base, w, xg, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0,
                              fb1, fpow, fw, False)
        x = search_next(st, y - yd, dy)
    guided_output(x, first, g, g1, g2, dt, base, w, xg, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw,
                  True)
    return x


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def guided_invert_steps(yd, mapped, dt, base, u_limit_lo, u_limit_hi, u_start, max_step, n_grid, tol, guide_c, r_lo,
                        r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """The reference-driven inverse over a record: (u, clipped) for desired outputs yd and the
    mapped reference ``mapped`` (one value per sample, ``mapped_reference``; the guide follows it
    through ``guide_step``)."""
    n = yd.shape[0]
    u_out = np.empty(n)
    clipped = np.zeros(n, dtype=np.bool_)
    w = np.zeros(r_lo.shape[0])
    xg = np.zeros(fa.shape[0])
    st = np.empty(SEARCH_SIZE)
    u1 = min(max(u_start, u_limit_lo), u_limit_hi)
    g1 = g2 = mapped[0]
    for k in range(n):
        first = k == 0
        g = guide_step(mapped[k], g1, g2, max_step, guide_c)
        x = guided_invert_sample(yd[k], g, first, u1, g1, g2, dt, base[k], u_limit_lo, u_limit_hi, max_step,
                                 n_grid, tol, st, w, xg, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow,
                                 fw)
        u_out[k] = x
        clipped[k] = search_clipped(st)
        u1 = x
        g2 = g if first else g1
        g1 = g
    return u_out, clipped


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def guided_simulate(u, guide, dt, base, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """The reference-driven model's output for input u and guide (``guided_output`` committed per
    sample): what the reference-driven inverse inverts exactly. With guide = u it is the model."""
    n = u.shape[0]
    out = np.empty(n)
    w = np.zeros(r_lo.shape[0])
    xg = np.zeros(fa.shape[0])
    g1 = g2 = guide[0]
    for k in range(n):
        first = k == 0
        out[k] = guided_output(u[k], first, guide[k], g1, g2, dt, base[k], w, xg, r_lo, r_hi, g_lo, g_hi, weights, poly,
                               q, fa, fb0, fb1, fpow, fw, True)[0]
        g2 = guide[k] if first else g1
        g1 = guide[k]
    return out


def guide_gain(s: "StepStructure", input_range) -> float:
    """The model's quasi-static gain: the secant of its first loading curve from rest (plays from 0,
    no rate terms, the filters at their steady state) over the input range; the reference-driven
    inverse maps the reference's changes to the input's by it."""
    lo, hi = map(float, input_range)

    def loading(u: float) -> float:
        plays = np.maximum(np.minimum(0.0, u + np.asarray(s.r_hi, dtype=float)), u - np.asarray(s.r_lo, dtype=float))
        poly = sum(c * u ** (j + 1) for j, c in enumerate(np.asarray(s.poly, dtype=float)))
        dc = np.asarray(s.filter_b0, dtype=float) + np.asarray(s.filter_b1, dtype=float)
        dc = np.divide(dc, 1.0 - np.asarray(s.filter_a, dtype=float), out=np.ones_like(dc), where=dc != 0)
        filters = float(np.sum(np.asarray(s.filter_weight, dtype=float) * dc * u ** np.asarray(s.filter_power)))
        return float(np.dot(np.asarray(s.weights, dtype=float), plays[:len(s.weights)])) + poly + filters

    return (loading(hi) - loading(lo)) / (hi - lo)


def mapped_reference(yd: np.ndarray, u_start: float, gain: float, y_first: float | None = None) -> np.ndarray:
    """The reference mapped to input units: u_start + (y_d(k) - y_d(0)) / gain (``y_first``: y_d(0)
    when yd does not start the record). The inverse stepper computes each value the same way."""
    y0 = float(yd[0]) if y_first is None else float(y_first)
    return u_start + (np.asarray(yd, dtype=float) - y0) * (1.0 / gain)


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def recursion_radius(u, dt, base, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw):
    """Per sample k of the forward model driven with u, the largest root modulus of the inverse's
    linearised error recursion c0 e(k) + c1 e(k-1) + c2 e(k-2) = 0, c_j = dy(k)/du(k-j) with the
    play and filter states held (module docstring, "Why the exact inverse diverges"), one-sided on
    the side of u(k-1) the input came from (the edges ``pi_sample``'s slope takes). 0 at the first
    two samples and where c0 = 0 (no root: the sample's input is not determined)."""
    n = u.shape[0]
    rho = np.zeros(n)
    w = np.zeros(r_lo.shape[0])
    xf = np.zeros(fa.shape[0])
    u1 = u2 = u[0]
    for k in range(n):
        if k >= 2:
            c0 = step_output(u[k], False, u1, u2, dt, base[k], w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                             fa, fb0, fb1, fpow, fw)[1]
            # c1 exactly, on the edges c0 was taken on: the slope without the rate terms (inv_dt = 0 in
            # the slope: no -/+ g a_i s / dt per play on an edge, no q / dt^2) minus c0 is the plays' c1
            # less q / dt^2; a finite difference in u1 would cross a play's edge whenever the play lies
            # within g / dt times its step of it, and report the other side's slope there
            inv_dt = 1.0 / dt
            a, s, d2 = backward_rates(u[k], u1, u2, False, inv_dt, inv_dt * inv_dt)
            rate_free = pi_sample(u[k], a, s, d2, False, u1, 0.0, base[k], w, xf, r_lo, r_hi, g_lo, g_hi, weights,
                                  poly, q, fa, fb0, fb1, fpow, fw, False, True)[1]
            c2 = q * inv_dt * inv_dt
            c1 = rate_free - c0 - c2
            for j in range(fa.shape[0]):
                pw = fpow[j]
                if pw != 0:
                    c1 += fw[j] * fb0[j] * pw * u1 ** (pw - 1)
            if c0 != 0.0:
                b = c1 / c0
                c = c2 / c0
                disc = b * b - 4.0 * c
                if disc >= 0.0:
                    sq = np.sqrt(disc)
                    rho[k] = max(abs(-b + sq), abs(-b - sq)) / 2.0
                else:
                    rho[k] = np.sqrt(abs(c))  # complex pair: |z|^2 = c
        step_commit(u[k], k == 0, u1, u2, dt, base[k], w, xf, r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                    fa, fb0, fb1, fpow, fw)
        u2 = u1
        u1 = u[k]
    return rho


@njit(cache=True, fastmath=KERNEL_FASTMATH)
def recursion_activity(u, dt, r_lo, r_hi, g_lo, g_hi, start, stop):
    """The operating point of the exact inverse's error recursion at samples [start, stop) of the
    forward model driven with u (plays from 0 at sample 0): per sample, each play's edge (1: on its
    lower edge u - g_lo |u'| - r_lo_i, -1: on its upper edge u + g_hi |u'| + r_hi_i, 0: held; the
    comparisons ``pi_sample``'s slope makes) and sign(u'). With these fixed, c0, c1, c2 of
    ``recursion_radius`` are linear in the weights, polynomial and q (``RecursionRows``)."""
    n_op = r_lo.shape[0]
    edge = np.zeros((stop - start, n_op), dtype=np.int8)
    sign = np.zeros(stop - start)
    w = np.zeros(n_op)
    inv_dt = 1.0 / dt
    u1 = u2 = u[0]
    for k in range(stop):
        a, s, _ = backward_rates(u[k], u1, u2, k == 0, inv_dt, inv_dt * inv_dt)
        for i in range(n_op):
            lower = u[k] - g_lo * a - r_lo[i]
            upper = u[k] + g_hi * a + r_hi[i]
            v = play_update(w[i], lower, upper)
            if k >= start:
                if v == lower:
                    edge[k - start, i] = 1
                elif v == upper:
                    edge[k - start, i] = -1
            w[i] = v
        if k >= start:
            sign[k - start] = s
        u2 = u1
        u1 = u[k]
    return edge, sign


@dataclass
class RecursionRows:
    """The exact inverse's error recursion c0 e(k) + c1 e(k-1) + c2 e(k-2) = 0 at operating points
    of a forward run (``recursion_radius``), as linear maps of the model's linear parameters:
    c_j = C_j @ theta_L (``linear_names`` order), one row per operating point."""

    c0: np.ndarray  # (n_points, n_linear)
    c1: np.ndarray
    c2: np.ndarray
    sample: np.ndarray  # the sample each point was taken at
    u: np.ndarray  # the input there
    sign: np.ndarray  # sign(u') there
    edge: np.ndarray  # (n_points, n_operators): 1 lower edge, -1 upper edge, 0 held (``recursion_activity``)
    dt: float

    @classmethod
    def stack(cls, parts: list["RecursionRows"]) -> "RecursionRows":
        cat = np.concatenate
        return cls(cat([p.c0 for p in parts]), cat([p.c1 for p in parts]), cat([p.c2 for p in parts]),
                   cat([p.sample for p in parts]), cat([p.u for p in parts]), cat([p.sign for p in parts]),
                   cat([p.edge for p in parts]), min((p.dt for p in parts), default=float("nan")))


@njit(cache=True)
def _edge_hash(edge):
    """FNV-1a hash of each row of ``edge`` (equal rows, equal hashes; ``distinct_operating_points``
    also compares the rows, so a collision merges nothing)."""
    out = np.empty(edge.shape[0], dtype=np.uint64)
    prime = np.uint64(1099511628211)
    for k in range(edge.shape[0]):
        h = np.uint64(14695981039346656037)
        for i in range(edge.shape[1]):
            h = (h ^ np.uint64(edge[k, i] + 1)) * prime
        out[k] = h
    return out


def distinct_operating_points(edge: np.ndarray, sign: np.ndarray, u: np.ndarray, input_range,
                              n_levels: int) -> np.ndarray:
    """Indices of a thinned set of operating points: c0, c1, c2 depend on a sample only through the
    plays' edges, sign(u') and u (the polynomial's slope); per (edges, sign, u in one of ``n_levels``
    equal bands of the input range) the samples with the smallest and the largest u are kept."""
    if u.size == 0:
        return np.zeros(0, dtype=np.int64)
    lo, hi = map(float, input_range)
    band = np.zeros(u.size, dtype=np.int64)
    if hi > lo:
        band = np.clip(np.floor((u - lo) / (hi - lo) * n_levels), 0, n_levels - 1).astype(np.int64)
    order = np.lexsort((u, band, sign, _edge_hash(np.ascontiguousarray(edge))))
    e, sg, b = edge[order], sign[order], band[order]
    new = np.ones(order.size, dtype=bool)
    new[1:] = (sg[1:] != sg[:-1]) | (b[1:] != b[:-1]) | np.any(e[1:] != e[:-1], axis=1)
    first = np.flatnonzero(new)
    last = np.concatenate([first[1:] - 1, [order.size - 1]])
    return np.unique(np.concatenate([order[first], order[last]]))


def reachable_operating_points(r_lo: np.ndarray, input_range, n_levels: int, g_lo: float = 0.0,
                               g_hi: float = 0.0) -> tuple:
    """Every operating point of ``recursion_activity`` that an input within ``input_range`` can reach
    (plays from 0 at sample 0, lower edges u - g_lo |u'| - r_lo_i with r_lo increasing from 0,
    upper edges u + g_hi |u'|): (edge, sign, u), u at the ``n_levels`` + 1 band ends of the range
    and at the ends of each pattern's interval.

    The plays share their edges but for r_lo, so from a common start their states are ordered
    (w_i >= w_j for r_i <= r_j: the clamp is monotone) and 1-Lipschitz in r (the clamp is
    1-Lipschitz in its bounds): the plays on the upper edge are plays 1..j, those on the lower edge
    plays 1..k. With g_lo, g_hi >= 0 both sets are nonempty only where play 1's edges meet (u' = 0,
    either label gives the same row), and a play's state stays within [min(0, lo), max(0, hi - r_i)]
    (only the edges move it, from 0): plays 1..k on the lower edge need u >= r_k + min(0, lo), plays
    1..j on the upper edge u <= max(0, hi - r_j). A negative rate coefficient lets fast inputs push
    the states beyond, and (g_lo + g_hi <= 0) cross or close the edges of plays 1..k, which then sit on the
    lower edge with k+1..j on the upper: every u and those mixed patterns are then taken. Each
    pattern with each sign(u') in {-1, 0, 1}: the rates' sizes only decide which of these points
    an input visits, not the recursion's coefficients there."""
    lo, hi = map(float, input_range)
    r = np.asarray(r_lo, dtype=float)
    n_op = r.size
    grid = np.linspace(lo, hi, int(n_levels) + 1)
    patterns = [(0, 0, lo, hi)]  # (plays on the lower edge, last play on the upper edge, u interval)
    if g_lo >= 0.0 and g_hi >= 0.0:
        patterns += [(k, 0, max(lo, r[k - 1] + min(0.0, lo)), hi) for k in range(1, n_op + 1)]
        patterns += [(0, j, lo, min(hi, max(0.0, hi - r[j - 1]))) for j in range(1, n_op + 1)]
    else:
        mixed = g_lo + g_hi <= 0.0
        patterns += [(k, j, lo, hi) for k in range(n_op + 1) for j in range(n_op + 1)
                     if (k, j) != (0, 0) and (j == 0 or (j > k and (mixed or k == 0)))]
    edges, signs, us = [], [], []
    for k, j, a, b in patterns:
        if a > b:
            continue
        u = np.unique(np.concatenate([grid[(grid > a) & (grid < b)], [a, b]]))
        edge = np.zeros(n_op, dtype=np.int8)
        edge[k:j] = -1
        edge[:k] = 1
        for s in (-1.0, 0.0, 1.0):
            edges.append(np.broadcast_to(edge, (u.size, n_op)))
            signs.append(np.full(u.size, s))
            us.append(u)
    return np.concatenate(edges), np.concatenate(signs), np.concatenate(us)


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

    def inverse_recursion_radius(self, u, dt: float, params, input_range=None) -> np.ndarray:
        """Per sample of the forward response to u: the largest root modulus of the exact inverse's
        linearised error recursion (``recursion_radius``). Above 1 the inverse amplifies any error in
        its input (rounding included) by that factor per sample."""
        u = self._check_input(u, dt)
        s = self._structure(dt, params, input_range if input_range is not None else (u.min(), u.max()), u.size)
        r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw = s.arguments()
        return recursion_radius(u, float(dt), np.ascontiguousarray(s.base), r_lo, r_hi, g_lo, g_hi, weights, poly, q,
                                fa, fb0, fb1, fpow, fw)

    def resolve_inverse(self, inverse: str, s: StepStructure, input_range) -> tuple[str, float]:
        """(the inverse that runs, the guide's gain: NaN for the exact inverse) for an ``inverse``
        option (``INVERSES``) and the model's step structure."""
        if inverse not in INVERSES:
            raise ModelError(f"{self.name}: inverse must be one of {', '.join(INVERSES)}; got {inverse!r}")
        dynamic = s.g_lo != 0.0 or s.g_hi != 0.0 or s.q != 0.0 or np.size(s.filter_a) > 0
        if inverse == "exact" or (inverse == "auto" and not dynamic):
            return "exact", float("nan")
        gain = guide_gain(s, input_range)
        if inverse == "auto" and not (gain > 0 and np.isfinite(gain)):
            return "exact", float("nan")  # no increasing loading curve to map the reference by
        if not (gain > 0 and np.isfinite(gain)):
            raise ModelError(f"{self.name}: the reference-driven inverse needs an increasing loading curve; its "
                             f"quasi-static gain over the input range is {gain:.4g} (use inverse='exact')")
        return "reference-driven", gain

    def invert(self, y_desired, dt: float, params, input_range=None, input_limits=None,
               n_grid: int = DEFAULT_GRID, max_rate: float | None = None, u_start: float | None = None,
               inverse: str = "auto", guide_time: float = DEFAULT_GUIDE_TIME) -> Inversion:
        """The causal numerical inverse: the input within ``input_limits`` (default: ``input_range``)
        that makes the model output ``y_desired``, sample by sample (module docstring).
        ``max_rate``: largest |du/dt| (input units per second; None: none); ``u_start``: the
        input before the first sample (default: the lower limit, an actuator at rest);
        ``inverse``: "exact", "reference-driven" or "auto" (``INVERSES``; the result names the one
        that ran and the exact inverse's recursion radius along its input); ``guide_time``: the
        reference-driven inverse's follower time constant (s, 0: none; ``guide_step``)."""
        a = InverseArguments.check(self.name, y_desired, dt, input_range, input_limits, n_grid, max_rate, u_start)
        guide_time = check_guide_time(self.name, guide_time)
        s = self._structure(dt, params, a.input_range, a.yd.size)
        inverse, gain = self.resolve_inverse(inverse, s, a.input_range)
        r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw = s.arguments()
        base = np.ascontiguousarray(s.base)
        if inverse == "exact":
            u, clipped = invert_steps(a.yd, float(dt), base, a.lo, a.hi, a.u_start, a.max_step, a.n_grid, a.tol,
                                      r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw)
        else:
            mapped = mapped_reference(a.yd, a.u_start, gain)
            u, clipped = guided_invert_steps(a.yd, mapped, float(dt), base, a.lo, a.hi, a.u_start, a.max_step,
                                             a.n_grid, a.tol, guide_rate(dt, guide_time), r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1,
                                             fpow, fw)
        radius = recursion_radius(u, float(dt), base, r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow,
                                  fw)
        return Inversion(u, clipped, inverse=inverse, exact_recursion_radius=float(np.max(radius, initial=0.0)))


def check_guide_time(name: str, guide_time) -> float:
    """The reference-driven inverse's follower time (s): 0 (none) or a positive, finite number."""
    if guide_time == 0 and not isinstance(guide_time, bool):
        return 0.0
    return check_number(name, "guide_time", guide_time, positive=True)


def check_max_rate(name: str, max_rate) -> float | None:
    """An inverse's |du/dt| limit: None (no limit) or a positive, finite number (not a bool)."""
    return None if max_rate is None else check_number(name, "max_rate", max_rate, positive=True)


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
        n_grid = check_int(name, "n_grid", n_grid, 2)
        max_rate = check_max_rate(name, max_rate)
        max_step = np.inf if max_rate is None else max_rate * float(dt)
        start = lo if u_start is None else check_number(name, "u_start", u_start)
        if not lo <= start <= hi:  # the input before the first sample is one the actuator can be at
            raise ModelError(f"{name}: u_start {start:g} is outside the input limits [{lo:g}, {hi:g}]")
        return cls(yd, tuple(map(float, input_range)), lo, hi, start, max_step, int(n_grid),
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
        return self._kernel_inverse(a, params, a.tol)

    def _kernel_inverse(self, a: "InverseArguments", params, tol: float) -> Inversion:
        vec, rng = self._step_setup(params, a.input_range)
        u, clipped, _ = self.step_kernel(a.yd, np.zeros(0), *self.step_arguments(vec, rng), a.lo, a.hi, a.u_start,
                                         a.max_step, a.n_grid, tol, self.clip_tolerance(vec, rng, tol))
        return Inversion(u, clipped)

    #: the model's ``KernelInverseStepper`` subclass (its per-sample search, the one its kernel runs)
    inverse_stepper_class = None

    def inverse_stepper(self, dt: float, params, input_range=None, input_limits=None, n_grid: int = DEFAULT_GRID,
                        max_rate: float | None = None, u_start: float | None = None,
                        reference_scale: float | None = None):
        """The inverse one sample at a time in constant time (the model's ``KernelInverseStepper``: the
        per-sample search its step kernel runs), equal to ``invert`` with the same options;
        ``reference_scale`` as ``PIInverseStepper``."""
        scale = abs(float(reference_scale)) if reference_scale is not None else 0.0
        a = InverseArguments.check(self.name, [scale], dt, input_range, input_limits, n_grid, max_rate, u_start)
        vec, rng = self._step_setup(params, a.input_range)
        return self.inverse_stepper_class(self, dt, vec, rng, a, self.clip_tolerance(vec, rng, a.tol))


class KernelInverseStepper(ArrayInverseStepper):
    """Base of the constant-time inverse steppers of the ``KernelInvertible`` models: the state is the
    forward stepper's array (``ArrayStepper``) plus the previous input u(k-1) where the forward state
    lacks it; each step is one call of the model's jitted per-sample inverse, the function its step
    kernel loops over (``search_start`` / ``search_next`` on the model's candidate output, then the
    forward stepper's commit). Subclasses set the fields and the rest state and implement
    ``_search(y_ref) -> u``."""

    def _inverse_setup(self, a: "InverseArguments", clip_tol: float) -> None:
        self.input_limits = (a.lo, a.hi)
        self.u_start = a.u_start
        self._limits = np.array([a.lo, a.hi, a.max_step, float(a.n_grid), a.tol, clip_tol])
        self._search_state = np.empty(SEARCH_SIZE)

    def _search(self, y_ref: float) -> float:
        raise NotImplementedError

    def _advance(self, y_ref: float) -> float:
        u = self._search(y_ref)
        self.clipped = bool(search_clipped(self._search_state))
        self.n_clipped += self.clipped
        return u


class ReplayInverseStepper(InverseStepper):
    """The inverse stepper of a model whose inverse has no per-sample form (no registered model: each
    has a constant-time inverse stepper): it keeps the references since ``reset`` and returns
    the last input of the model's causal inverse over them (causal: the input the batch inverse
    gives at that sample). Exact, O(k) per step: for tests and offline loops, not for a real-time
    target. ``invert_prefix(references) -> Inversion`` is the model's inverse with its options bound."""

    def __init__(self, model, dt: float, invert_prefix):
        self.model, self.dt, self._invert = model, float(dt), invert_prefix
        self.reset()

    def reset(self) -> None:
        self._refs: list[float] = []
        self.clipped = False
        self.n_clipped = 0

    def step(self, y_ref: float) -> float:
        self._refs.append(check_step_input(self.model.name, y_ref))
        inv = self._invert(np.array(self._refs))
        self.clipped = bool(inv.clipped[-1])
        self.n_clipped += self.clipped
        return float(inv.u[-1])

    @property
    def state(self) -> dict:
        return {"references": list(self._refs), "n_clipped": int(self.n_clipped)}

    def set_state(self, state: dict) -> None:
        state = check_state_keys(self.model.name, state, ("references", "n_clipped"))
        self._refs = [float(v) for v in state["references"]]
        self.n_clipped = int(state["n_clipped"])


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
    loading curve does not increase (no P-I inverse exists) and where the initial states are no memory
    an input history can leave (|p_{i+1} - p_i| <= h_{i+1} - h_i): the inverse's initial states
    q_i = A_i p_i + sum_{j>i} a_j p_j reproduce the input only from such a memory."""
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
    if p.shape != h.shape:
        raise ModelError(f"classical P-I: {p.size} initial play states for {h.size} thresholds")
    gap = np.abs(np.diff(p)) - np.diff(h)
    if np.any(gap > 1e-12 * (1.0 + np.max(np.abs(p), initial=0.0))):
        raise ModelError("classical P-I: the analytic inverse needs initial play states an input history can "
                         "leave (|p_{i+1} - p_i| <= h_{i+1} - h_i; exceeded by "
                         f"{float(np.max(gap)):.3g}): from other states it does not reproduce the input")
    previous = np.concatenate(([a0], cumulative[:-1]))  # A_{i-1}
    s = np.array([a0 * h[i] + float(np.sum(a[:i] * (h[i] - h[:i]))) for i in range(h.size)])
    b = -a / (cumulative * previous)
    tail = np.concatenate((np.cumsum((a * p)[::-1])[::-1][1:], [0.0]))  # sum_{j>i} a_j p_j
    q0 = cumulative * p + tail
    return _pi_operator(np.ascontiguousarray(z, dtype=float), 1.0 / a0, b, s, q0)
