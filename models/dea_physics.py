"""The virtual DEA's physics kernel: one time loop, shared by the data
generator (``hysbench.data.virtual_dea``) and the registry model
``viscoelastic`` (``hysbench.models.viscoelastic``).

The equations are stated in the docstring of ``hysbench.data.virtual_dea``.
Here: the physical parameters (``DEAParameters``, the calibrated ``TRUTH``), the
parameter vector's layout, and the numba kernels.

Physical parameter vector (SI units), ``PHYS_NAMES`` order, then the branches:

    mu, J, eta_v, lam0, lam_t, L_active, L_passive, H, eps_r,
    mu_1 .. mu_K, tau_1 .. tau_K

Integration: classical Runge-Kutta 4 on the state
[lam_a, (xi, xi_t) per branch of the active region, the same for the passive
region], with the input linearly interpolated between samples (first-order
hold of the commanded voltage) and ``n_sub`` RK4 substeps per sample, chosen
per parameter set from a Gershgorin bound of the Jacobian at the initial state
so that the step stays well inside RK4's stability region (one substep for
the virtual DEA at 1 ms). ``simulate_window_batch`` stores only a window and
may cross the samples before it with longer RK4 steps (``warmup_stride``
samples, bounded by stability: WARMUP_RATE_STEP_LIMIT); the data generator
never does. A parameter set for which a Gent denominator
reaches zero or the state stops being finite (lock-up, loss of stability) gets
NaN from that sample on: identifiers must read NaN as "infeasible".
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numba import njit, prange

from hysbench.models.errors import HysbenchError

EPS0 = 8.8541878128e-12  # vacuum permittivity, F/m
PHYS_NAMES = ("mu", "J", "eta_v", "lam0", "lam_t", "L_active", "L_passive", "H", "eps_r")
N_FIXED = len(PHYS_NAMES)
# The largest |Jacobian| * substep we allow (RK4 is stable up to about 2.8 on
# the negative real axis; 0.25 keeps the local error tiny).
RATE_STEP_LIMIT = 0.25
# Before the stored window (warm-up) the step may be longer: stability, not accuracy, is what matters there.
WARMUP_RATE_STEP_LIMIT = 1.0
MAX_SUBSTEPS = 64


@dataclass(frozen=True)
class DEAParameters:
    """Physical parameters of the virtual DEA (SI units)."""

    mu: float  # Gent spring modulus, Pa
    J: float  # Gent limit of every element
    eta_v: float  # parallel dashpot viscosity, Pa s
    mu_k: tuple[float, ...]  # branch moduli, Pa
    tau_k: tuple[float, ...]  # branch relaxation times eta_k / mu_k, s
    lam0: float = 6.0  # prestretch along the actuation direction
    lam_t: float = 4.0  # transverse prestretch (held by the frame)
    L_active: float = 14e-3  # unstretched length of the active region along the actuation direction, m
    L_passive: float = 14e-3  # the same for the passive region, m
    H: float = 0.5e-3  # unstretched thickness, m (VHB 4905)
    eps_r: float = 4.5  # relative permittivity

    def __post_init__(self):
        if len(self.mu_k) != len(self.tau_k):
            raise HysbenchError("DEAParameters: mu_k and tau_k must have the same length")
        values = (self.mu, self.J, self.eta_v, self.lam0, self.lam_t, self.L_active, self.L_passive, self.H,
                  self.eps_r, *self.mu_k, *self.tau_k)
        if not all(math.isfinite(v) and v > 0 for v in values):
            raise HysbenchError(f"DEAParameters: every parameter must be finite and positive: {self}")

    @property
    def n_branches(self) -> int:
        return len(self.mu_k)

    def vector(self) -> np.ndarray:
        """The physical parameter vector of ``dea_physics`` (``PHYS_NAMES`` then mu_k, tau_k)."""
        return np.array([self.mu, self.J, self.eta_v, self.lam0, self.lam_t, self.L_active, self.L_passive,
                         self.H, self.eps_r, *self.mu_k, *self.tau_k], dtype=float)

    def with_changes(self, **changes) -> "DEAParameters":
        return replace(self, **changes)

    def as_dict(self) -> dict:
        return {
            "mu_Pa": self.mu, "J": self.J, "eta_v_Pa_s": self.eta_v,
            "branches": [{"mu_Pa": m, "tau_s": t} for m, t in zip(self.mu_k, self.tau_k)],
            "lam0": self.lam0, "lam_t": self.lam_t, "L_active_m": self.L_active, "L_passive_m": self.L_passive,
            "H_m": self.H, "eps_r": self.eps_r,
        }


# A known-good parameter set: the calibration's starting point (``--start issue``).
ISSUE_START = DEAParameters(mu=7.85e3, J=100.0, eta_v=15.9e3, mu_k=(178e3, 117e3, 351e3), tau_k=(0.268, 2.03, 58.6))

# Calibrated by ``python -m hysbench.data.calibrate_virtual_dea`` from ISSUE_START (rounded to
# three significant digits; see results/virtual_dea.md for the figures it gives).
TRUTH = DEAParameters(mu=7870.0, J=100.0, eta_v=15900.0, mu_k=(178e3, 117e3, 349e3), tau_k=(0.268, 2.03, 58.2))


@njit(cache=True, fastmath=False)
def _rhs(state, u_kv, p, n_br, inv_6tau, out):
    """Time derivative of the state; returns False if a Gent limit is reached.

    ``inv_6tau[k]`` = 1 / (6 tau_k), precomputed by the caller.
    """
    mu = p[0]
    inv_j = 1.0 / p[1]
    eta_v = p[2]
    lam0 = p[3]
    lam_t = p[4]
    ratio = p[5] / p[6]  # L_active / L_passive
    lt2 = lam_t * lam_t
    inv_lt = 1.0 / lam_t
    inv_lt2 = inv_lt * inv_lt
    lam_a = state[0]
    lam_p = lam0 - ratio * (lam_a - lam0)
    if lam_a <= 0.0 or lam_p <= 0.0:
        return False
    s_a = 0.0
    s_p = 0.0
    for reg in range(2):
        lam = lam_a if reg == 0 else lam_p
        inv_lam = 1.0 / lam
        l2 = lam * lam
        il2 = inv_lam * inv_lam
        # Gent spring
        den = 1.0 - (l2 + lt2 + il2 * inv_lt2 - 3.0) * inv_j
        if den <= 0.0:
            return False
        s = mu / den * (lam - il2 * inv_lam * inv_lt2)
        # Gent-Maxwell branches, Zhao-Koh-Suo flow rule
        for k in range(n_br):
            j = 1 + 2 * (reg * n_br + k)
            xi = state[j]
            xi_t = state[j + 1]
            e1 = lam / xi  # elastic stretches of the branch spring
            e2 = lam_t / xi_t
            e3 = xi * xi_t * inv_lam * inv_lt
            a1 = e1 * e1
            a2 = e2 * e2
            a3 = e3 * e3
            den_k = 1.0 - (a1 + a2 + a3 - 3.0) * inv_j
            if den_k <= 0.0:
                return False
            g = 1.0 / den_k
            s += p[N_FIXED + k] * g * (a1 - a3) * inv_lam
            rate = g * inv_6tau[k]
            out[j] = xi * rate * (2.0 * a1 - a2 - a3)
            out[j + 1] = xi_t * rate * (2.0 * a2 - a1 - a3)
        if reg == 0:
            s_a = s
        else:
            s_p = s
    # ideal dielectric: Maxwell stress eps (Phi/h)^2, h = H / (lam lam_t), as nominal stress along lam
    phi = u_kv * 1e3
    h_ref = p[7]
    s_maxwell = p[8] * EPS0 * phi * phi * lam_a * lt2 / (h_ref * h_ref)
    # parallel dashpot: nominal stress 4 eta_v lam' / lam^2 in each region; platform force balance
    c_a = 4.0 * eta_v / (lam_a * lam_a)
    c_p = 4.0 * eta_v / (lam_p * lam_p)
    out[0] = (s_p - s_a + s_maxwell) / (c_a + ratio * c_p)
    return True


@njit(cache=True)
def _inv_6tau(p, n_br):
    out = np.empty(n_br)
    for k in range(n_br):
        out[k] = 1.0 / (6.0 * p[N_FIXED + n_br + k])
    return out


@njit(cache=True)
def _initial_state(p, n_br, state):
    state[0] = p[3]
    for reg in range(2):
        for k in range(n_br):
            j = 1 + 2 * (reg * n_br + k)
            state[j] = p[3]
            state[j + 1] = p[4]


@njit(cache=True)
def _substeps(u0, dt, p, n_br, limit=RATE_STEP_LIMIT):
    """RK4 substeps per sample from a Gershgorin bound of the Jacobian at the initial state."""
    n = 1 + 4 * n_br
    x = np.empty(n)
    f0 = np.empty(n)
    f1 = np.empty(n)
    _initial_state(p, n_br, x)
    inv_6tau = _inv_6tau(p, n_br)
    if not _rhs(x, u0, p, n_br, inv_6tau, f0):
        return 1
    row = np.zeros(n)
    for j in range(n):
        h = 1e-7 * abs(x[j]) + 1e-10
        xj = x[j]
        x[j] = xj + h
        ok = _rhs(x, u0, p, n_br, inv_6tau, f1)
        x[j] = xj
        if not ok:
            continue
        for i in range(n):
            row[i] += abs((f1[i] - f0[i]) / h)
    bound = 0.0
    for i in range(n):
        bound = max(bound, row[i])
    m = int(math.ceil(dt * bound / limit))
    return min(max(m, 1), MAX_SUBSTEPS)


@njit(cache=True)
def _rk4_step(x, ua, um, ub, h, p, n_br, inv_6tau, k1, k2, k3, k4, tmp):
    """One classical RK4 step of length h with the input ua, um, ub at its start, middle, end."""
    n = x.shape[0]
    ok = _rhs(x, ua, p, n_br, inv_6tau, k1)
    for j in range(n):
        tmp[j] = x[j] + 0.5 * h * k1[j]
    ok = ok and _rhs(tmp, um, p, n_br, inv_6tau, k2)
    for j in range(n):
        tmp[j] = x[j] + 0.5 * h * k2[j]
    ok = ok and _rhs(tmp, um, p, n_br, inv_6tau, k3)
    for j in range(n):
        tmp[j] = x[j] + h * k3[j]
    ok = ok and _rhs(tmp, ub, p, n_br, inv_6tau, k4)
    if not ok:
        return False
    for j in range(n):
        x[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j])
    return math.isfinite(x[0])


@njit(cache=True)
def _advance(x, ua, ub, h, m, p, n_br, inv_6tau, k1, k2, k3, k4, tmp):
    """One sample interval: m RK4 substeps of length h, the input linear from ua to ub."""
    du = (ub - ua) / m
    for s in range(m):
        u0 = ua + du * s
        if not _rk4_step(x, u0, u0 + 0.5 * du, u0 + du, h, p, n_br, inv_6tau, k1, k2, k3, k4, tmp):
            return False
    return True


@njit(cache=True)
def advance_sample(x, ua, ub, dt, m, p, n_br):
    """Advance the state x in place over one sample of length dt (m RK4 substeps, the input linear
    from ua to ub): the plant stepped with a controller in the loop. Returns False on failure."""
    n = x.shape[0]
    return _advance(x, ua, ub, dt / m, m, p, n_br, _inv_6tau(p, n_br), np.empty(n), np.empty(n), np.empty(n),
                    np.empty(n), np.empty(n))


@njit(cache=True)
def stepper_sample(u_kv, dt, p, n_br, x, head, inv_6tau, work):
    """One sample of the viscoelastic stepper: lam_a(t_k) - lam0 for input u_kv at this sample,
    the state ``x`` advanced in place over the interval from the previous input (``_advance``, as
    ``_simulate_one``). head = [first, u(k-1) (kV), substeps m, failed]: at the first sample m is
    set from its input (as ``_simulate_one`` sets it from u(0)) and the state is the rest state;
    after a failure every sample is NaN. work: (5, len(x)) scratch."""
    if head[0] != 0.0:
        head[0] = 0.0
        head[2] = _substeps(u_kv, dt, p, n_br)
    elif head[3] == 0.0:
        m = int(head[2])
        if not _advance(x, head[1], u_kv, dt / m, m, p, n_br, inv_6tau, work[0], work[1], work[2], work[3], work[4]):
            head[3] = 1.0
    head[1] = u_kv
    return np.nan if head[3] != 0.0 else x[0] - p[3]


@njit(cache=True)
def invert_stretch(dlam, dt, p, n_br, u_lo, u_hi, u_start, max_step, tol):
    """The causal inverse of the physics: (u_kv, clipped) with lam_a(t_k) - lam0 = dlam[k].

    The stretch at t_k depends on u_k only through the interval [t_{k-1}, t_k] (input linear
    from u_{k-1}): at each sample the scalar equation is solved on [u_lo, u_hi] narrowed to
    u_{k-1} +- max_step (bisection with regula falsi steps; the Maxwell stress makes the
    stretch increase with a positive input), then the state advances. Sample 0 is the rest
    state whatever the input (u_0 = u_start): clipped unless dlam[0] is 0. A desired
    stretch beyond both ends of the interval takes the nearer end, counted as clipped.
    """
    n = dlam.shape[0]
    u = np.empty(n)
    clipped = np.zeros(n, dtype=np.bool_)
    x = initial_state(p, n_br)
    trial = np.empty_like(x)
    k1, k2, k3, k4, tmp = np.empty_like(x), np.empty_like(x), np.empty_like(x), np.empty_like(x), np.empty_like(x)
    inv_6tau = _inv_6tau(p, n_br)
    u[0] = u_start
    clipped[0] = abs(dlam[0]) > tol
    m = _substeps(u_start, dt, p, n_br)
    h = dt / m
    for k in range(1, n):
        uk, clip, ok = _invert_sample(dlam[k], x, u[k - 1], u_lo, u_hi, max_step, tol, h, m, p, n_br, inv_6tau,
                                      trial, k1, k2, k3, k4, tmp)
        if not ok:
            u[k:] = np.nan
            clipped[k:] = True
            break
        u[k] = uk
        clipped[k] = clip
    return u, clipped


@njit(cache=True)
def _invert_sample(target, x, u1, u_lo, u_hi, max_step, tol, h, m, p, n_br, inv_6tau, trial, k1, k2, k3, k4, tmp):
    """One sample of the inverse (``invert_stretch``): (u_k, clipped, ok) for the desired stretch
    ``target`` from the state x after the previous input u1; x is advanced in place to u_k. ok is
    False (x untouched) where the stretch at the interval's ends is not finite."""
    lam0 = p[3]
    lo = max(u_lo, u1 - max_step)
    hi = min(u_hi, u1 + max_step)
    trial[:] = x
    _advance(trial, u1, lo, h, m, p, n_br, inv_6tau, k1, k2, k3, k4, tmp)
    g_lo = trial[0] - lam0 - target
    trial[:] = x
    _advance(trial, u1, hi, h, m, p, n_br, inv_6tau, k1, k2, k3, k4, tmp)
    g_hi = trial[0] - lam0 - target
    if not (np.isfinite(g_lo) and np.isfinite(g_hi)):
        return np.nan, True, False
    clipped = False
    if (g_lo > 0) == (g_hi > 0) and abs(g_lo) > tol and abs(g_hi) > tol:
        uk = lo if abs(g_lo) < abs(g_hi) else hi
        clipped = True
    else:
        a, ga, b, gb = lo, g_lo, hi, g_hi
        uk = a if abs(ga) < abs(gb) else b
        for it in range(100):
            if abs(ga) <= tol or abs(gb) <= tol or b - a <= 1e-14 * (abs(a) + abs(b)):
                break
            c = b - gb * (b - a) / (gb - ga) if it % 2 == 0 else 0.5 * (a + b)  # secant, then bisection
            if not a < c < b:
                c = 0.5 * (a + b)
            trial[:] = x
            _advance(trial, u1, c, h, m, p, n_br, inv_6tau, k1, k2, k3, k4, tmp)
            gc = trial[0] - lam0 - target
            if (gc > 0) == (ga > 0):
                a, ga = c, gc
            else:
                b, gb = c, gc
        uk = a if abs(ga) < abs(gb) else b
    _advance(x, u1, uk, h, m, p, n_br, inv_6tau, k1, k2, k3, k4, tmp)
    return uk, clipped, True


@njit(cache=True)
def inverse_stepper_sample(target, dt, p, n_br, x, head, limits, inv_6tau, work):
    """One sample of the viscoelastic inverse stepper: the input (kV) for the desired stretch ``target``
    at this sample, the state advanced (``_invert_sample``, as ``invert_stretch``). head = [first,
    u(k-1) (kV), substeps m, failed, clipped (out)]; limits = [u_lo, u_hi, u_start, max_step, tol] (kV);
    work: (6, len(x)) scratch. The first sample is the rest state, its input u_start (clipped unless
    the target is 0); after a failure every input is NaN (clipped)."""
    if head[0] != 0.0:
        head[0] = 0.0
        head[1] = limits[2]
        head[2] = _substeps(limits[2], dt, p, n_br)
        head[4] = 1.0 if abs(target) > limits[4] else 0.0
        return limits[2]
    if head[3] != 0.0:
        head[4] = 1.0
        return np.nan
    m = int(head[2])
    uk, clip, ok = _invert_sample(target, x, head[1], limits[0], limits[1], limits[3], limits[4], dt / m, m, p, n_br,
                                  inv_6tau, work[0], work[1], work[2], work[3], work[4], work[5])
    if not ok:
        head[3] = 1.0
        head[4] = 1.0
        return np.nan
    head[1] = uk
    head[4] = 1.0 if clip else 0.0
    return uk


@njit(cache=True)
def _input_at(u_kv, q):
    """The input at fractional sample position q (linear between samples)."""
    k = min(int(q), u_kv.shape[0] - 2)
    return u_kv[k] + (q - k) * (u_kv[k + 1] - u_kv[k])


@njit(cache=True)
def _simulate_one(u_kv, dt, p, n_br, out, x, start, warmup_stride):
    """out[k - start] = lam_a(t_k) - lam0 for k in [start, start + len(out)), simulated from the
    state ``x`` at t_0 (which is advanced in place); NaN from a failure on. Stops at the last
    sample stored.

    Before ``start`` (warm-up, not stored), RK4 steps may span ``warmup_stride`` samples (input
    linear between samples); from ``start`` on, and everywhere when warmup_stride is 1, each
    sample interval is integrated with its own RK4 (sub)steps.
    """
    n = 1 + 4 * n_br
    k1 = np.empty(n)
    k2 = np.empty(n)
    k3 = np.empty(n)
    k4 = np.empty(n)
    tmp = np.empty(n)
    lam0 = p[3]
    inv_6tau = _inv_6tau(p, n_br)
    last = start + out.shape[0] - 1
    ok = True
    i0 = 0
    if warmup_stride > 1 and start >= warmup_stride:
        ms = _substeps(u_kv[0], dt * warmup_stride, p, n_br, WARMUP_RATE_STEP_LIMIT)
        hs = dt * warmup_stride / ms
        while ok and i0 + warmup_stride <= start:
            for s in range(ms):
                qa = i0 + warmup_stride * s / ms
                qm = i0 + warmup_stride * (s + 0.5) / ms
                qb = i0 + warmup_stride * (s + 1.0) / ms
                ok = _rk4_step(x, _input_at(u_kv, qa), _input_at(u_kv, qm), _input_at(u_kv, qb), hs, p, n_br,
                               inv_6tau, k1, k2, k3, k4, tmp)
                if not ok:
                    break
            i0 += warmup_stride
        if not ok:
            out[:] = np.nan
            return
    m = _substeps(u_kv[0], dt, p, n_br)
    h = dt / m
    for i in range(i0, last + 1):
        if i >= start:
            out[i - start] = x[0] - lam0
        if i == last:
            break
        ok = _advance(x, u_kv[i], u_kv[i + 1], h, m, p, n_br, inv_6tau, k1, k2, k3, k4, tmp)
        if not ok:
            for r in range(max(i + 1, start), last + 1):
                out[r - start] = np.nan
            break


@njit(cache=True, parallel=True)
def simulate_window_batch(u_kv, dt, phys, n_br, start, stop, warmup_stride=1):
    """lam_a(t_k) - lam0 for k in [start, stop), each row of ``phys`` simulated from t_0:
    shape (n_sets, stop - start). Only the window is stored; ``warmup_stride`` > 1 takes
    longer steps before it (see ``_simulate_one``)."""
    n_set = phys.shape[0]
    out = np.empty((n_set, stop - start))
    for s in prange(n_set):
        x = np.empty(1 + 4 * n_br)
        _initial_state(phys[s], n_br, x)
        _simulate_one(u_kv, dt, phys[s], n_br, out[s], x, start, warmup_stride)
    return out


def simulate_stretch_batch(u_kv, dt, phys, n_br):
    """lam_a(t_k) - lam0 for each row of ``phys``: shape (n_sets, n_samples)."""
    return simulate_window_batch(u_kv, dt, phys, n_br, 0, u_kv.shape[0])


@njit(cache=True)
def simulate_stretch(u_kv, dt, phys, n_br):
    """lam_a(t_k) - lam0 for one parameter vector (serial)."""
    out = np.empty(u_kv.shape[0])
    x = np.empty(1 + 4 * n_br)
    _initial_state(phys, n_br, x)
    _simulate_one(u_kv, dt, phys, n_br, out, x, 0, 1)
    return out


@njit(cache=True)
def simulate_from(u_kv, dt, phys, n_br, state):
    """Like ``simulate_stretch`` but from a given state, which is advanced in place (analysis)."""
    out = np.empty(u_kv.shape[0])
    _simulate_one(u_kv, dt, phys, n_br, out, state, 0, 1)
    return out


@njit(cache=True)
def state_derivative(state, u_kv, phys, n_br):
    """The right-hand side (for linearisation and tests); NaN where a Gent limit is reached."""
    out = np.zeros(state.shape[0])
    if not _rhs(state, u_kv, phys, n_br, _inv_6tau(phys, n_br), out):
        out[:] = np.nan
    return out


@njit(cache=True)
def initial_state(phys, n_br):
    x = np.empty(1 + 4 * n_br)
    _initial_state(phys, n_br, x)
    return x


@njit(cache=True)
def substeps(u0_kv, dt, phys, n_br):
    return _substeps(u0_kv, dt, phys, n_br)
