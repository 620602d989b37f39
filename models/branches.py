"""Shared machinery of the two branch-switching models (``elliptical``,
``dual-polynomial``): the input normalised over its range, the direction of
travel, and one rule that keeps the output continuous at reversals.

Both models give the output on two branches of the normalised input
xi in [-1, 1] (xi = -1 at the range's lower end, +1 at its upper end):

    y = c + M(xi) - s H(xi)

with s = +1 while the input rises (ascending branch) and s = -1 while it
falls. M is the loop's centre line, H its half-width; H(+-1) = 0, so the two
branches meet at the ends of the range and the major loop is closed and
continuous.

Direction s(k): the sign of u(k) - u(k-1); where the input does not change,
the previous direction is kept; s(0) = +1 (the record is taken to start
rising, as the paper's drive does from its minimum).

Reversals inside the range (minor loops): a plain branch switch would jump by
2 H(xi_t). We keep the output continuous with a one-reversal memory: after a
reversal at xi_t, where the output was y_t, the new branch B is followed as

    y = B(xi) + (y_t - B(xi_t)) w(xi),
    w = (1 - xi) / (1 - xi_t)  rising,    w = (1 + xi) / (1 + xi_t)  falling,

clipped to [0, 1]: the offset from the major branch decays linearly to zero at
the end of the range the input is moving towards. A reversal at the range's
end (the major loop) leaves no offset, so there the model is exactly the
published two-branch form. Outside the range (an input beyond
``input_range``) H is evaluated at the clipped xi (the loop is closed there)
and M is extrapolated.

Every output sample is linear in the coefficients of M and H (the reversal
value y_t is itself such a combination), so the model is linear in all its
parameters: ``branch_regressors`` runs the rule on each basis function,
one ``branch_step`` per sample.

Inverse (``KernelInvertible.invert``, kernel ``branch_steps``, the same ``branch_step``): at
each sample y is continuous in u: both branches leave the previous output (at a reversal
the memory starts the new branch there), so the search, walking out from u(k-1), takes the
root nearest the previous input. Not invertible, so clipped to the nearest output the walk
visits and counted: a desired output beyond those reachable within the limits (and the rate
limit) on the branch the input would take, or behind a flat or turning stretch of it (a
branch not monotone in u; each model's docstring says where its shape does that). A
turning stretch narrower than the walk's step (range / n_grid) that alone holds the root is
stepped over.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .base import DataScale, HysteresisModel, Parameter
from .errors import ModelError
from .hyperparameters import check_bool
from .inverse import KernelInverseStepper, KernelInvertible
from .root_search import SEARCH_SIZE, search_clipped, search_done, search_next, search_start
from .stepper import ArrayStepper, stepper_input_range


def normalised_input(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """xi = (2x - (hi + lo)) / (hi - lo): -1 at lo, +1 at hi."""
    if not hi > lo:
        raise ModelError(f"input range must have positive width, got ({lo!r}, {hi!r})")
    return (2.0 * x - (hi + lo)) / (hi - lo)


@njit(cache=True)
def direction(u):
    """+1 rising, -1 falling; held where the input is constant; +1 at the start."""
    n = u.shape[0]
    s = np.empty(n, dtype=np.int8)
    cur = 1
    for k in range(n):
        if k > 0:
            d = u[k] - u[k - 1]
            if d > 0.0:
                cur = 1
            elif d < 0.0:
                cur = -1
        s[k] = cur
    return s


ELLIPSE, POLYNOMIAL = 0, 1  # half-width bases: sqrt(1 - x^2); (1 - x^2) x^j, j = 0..n_half-1


@njit(cache=True, nogil=True)
def branch_basis(xi, kind, G, K):
    """The bases at one sample, in place: G = xi^1 .. xi^nm (centre line M) and K at the
    clipped xi (half-width H, ``kind`` ELLIPSE or POLYNOMIAL), by repeated products."""
    col = 1.0
    for j in range(G.shape[0] + 1):
        if j >= 1:
            G[j - 1] = col
        col = col * xi
    xc = min(max(xi, -1.0), 1.0)
    if kind == ELLIPSE:
        K[0] = np.sqrt(max(1.0 - xc * xc, 0.0))
    else:
        envelope = 1.0 - xc * xc
        col = 1.0
        for j in range(K.shape[0]):
            K[j] = envelope * col
            col = col * xc


@njit(cache=True, nogil=True)
def branch_step(xi, sk, reversal, xi_prev, xi_t, G_prev, K_prev, prev_row, jump, G, K, row):
    """One sample of the rule (module docstring) on every basis column: the row at xi on branch
    sk into ``row``, from the bases G, K at xi. At a reversal the memory ``jump`` (in place) takes
    the previous row's offset from the new branch at the previous sample (bases G_prev, K_prev).
    Returns the reversal point xi_t in force."""
    nm = G.shape[0]
    nh = K.shape[0]
    if reversal:
        xi_t = xi_prev
        for j in range(nm):
            jump[j] = prev_row[j] - G_prev[j]
        for j in range(nh):
            jump[nm + j] = prev_row[nm + j] + sk * K_prev[j]
    # decay weight of the memory
    if sk > 0:
        den = 1.0 - xi_t
        w = (1.0 - xi) / den if den > 1e-12 else 0.0
    else:
        den = 1.0 + xi_t
        w = (1.0 + xi) / den if den > 1e-12 else 0.0
    if w < 0.0:
        w = 0.0
    elif w > 1.0:
        w = 1.0
    for j in range(nm):
        row[j] = G[j] + jump[j] * w
    for j in range(nh):
        row[nm + j] = -sk * K[j] + jump[nm + j] * w
    return xi_t


@njit(cache=True)
def branch_regressors(xi, s, n_centre, kind, n_half):
    """Columns of y - c for unit coefficients: first M's n_centre basis functions, then H's
    n_half (column value on branch s: G or -s K, with the reversal memory), one
    ``branch_step`` per sample."""
    n_t = xi.shape[0]
    out = np.empty((n_t, n_centre + n_half))
    jump = np.zeros(n_centre + n_half)
    G, G_prev = np.zeros(n_centre), np.zeros(n_centre)
    K, K_prev = np.zeros(n_half), np.zeros(n_half)
    xi_t = 0.0
    for k in range(n_t):
        branch_basis(xi[k], kind, G, K)
        reversal = k > 0 and s[k] != s[k - 1]
        xi_t = branch_step(xi[k], s[k], reversal, xi[k - 1] if k > 0 else 0.0, xi_t, G_prev, K_prev,
                           out[k - 1] if k > 0 else out[0], jump, G, K, out[k])
        G_prev[:] = G
        K_prev[:] = K
    return out


@njit(cache=True, nogil=True)
def branch_candidate(u, first, u1, s_prev, xi_prev, xi_t, jump, G_prev, K_prev, prev_row, coef, offset, x_lo, x_hi,
                     square, kind, G, K, jump_c, row):
    """(y, xi, direction, xi_t) at this sample for input u, the state after the previous sample
    (u1 = u(k-1), s_prev, xi_prev, xi_t, jump, G_prev, K_prev, prev_row) unchanged; the bases,
    memory and row at u go to G, K, jump_c, row. y = offset + coef . row; the rule on
    x = u |u| if ``square`` else u, normalised over [x_lo, x_hi]."""
    sk = 1 if first else (1 if u > u1 else (-1 if u < u1 else s_prev))
    x = u * abs(u) if square else u
    xi = (2.0 * x - (x_hi + x_lo)) / (x_hi - x_lo)
    branch_basis(xi, kind, G, K)
    jump_c[:] = jump
    xt = branch_step(xi, sk, (not first) and sk != s_prev, xi_prev, xi_t, G_prev, K_prev, prev_row, jump_c, G, K, row)
    y = offset
    for j in range(row.shape[0]):
        y += coef[j] * row[j]
    return y, xi, sk, xt


STATE_HEAD = 5  # first, u(k-1), direction, xi(k-1), xi_t


@njit(cache=True, nogil=True)
def state_views(state, work, n_centre, n_half):
    """The stepper state's parts (memory, previous bases, previous row) and the scratch parts, as views."""
    nc = n_centre + n_half
    o = STATE_HEAD
    return (state[o:o + nc], state[o + nc:o + nc + n_centre], state[o + nc + n_centre:o + 2 * nc],
            state[o + 2 * nc:o + 3 * nc], work[:n_centre], work[n_centre:nc], work[nc:2 * nc], work[2 * nc:3 * nc])


@njit(cache=True, nogil=True)
def branch_advance(u, state, coef, offset, x_lo, x_hi, square, kind, n_centre, n_half, work):
    """One sample of ``BranchStepper``: ``branch_candidate`` at u from the state after the previous
    sample, then committed (as ``branch_steps`` commits). state = [first, u(k-1), direction,
    xi(k-1), xi_t, jump (nc), G_prev (n_centre), K_prev (n_half), prev_row (nc)]; work: 2 nc
    floats of scratch. Returns y(k)."""
    jump, G_prev, K_prev, prev_row, G, K, jump_c, row = state_views(state, work, n_centre, n_half)
    y, xi, sk, xt = branch_candidate(u, state[0] != 0.0, state[1], int(state[2]), state[3], state[4], jump, G_prev,
                                     K_prev, prev_row, coef, offset, x_lo, x_hi, square, kind, G, K, jump_c, row)
    jump[:] = jump_c
    prev_row[:] = row
    G_prev[:] = G
    K_prev[:] = K
    state[0] = 0.0
    state[1] = u
    state[2] = sk
    state[3] = xi
    state[4] = xt
    return y


class BranchStepper(ArrayStepper):
    """The constant-time stepper of the branch models: state (first, u(k-1), direction, xi(k-1), the
    reversal point xi_t, the memory, the previous bases and row); each step is ``branch_step``, the
    per-sample rule ``branch_regressors`` runs. The output is offset + coefficients . row, summed in
    order (``simulate`` takes the same sum as one matrix product: equal to rounding, ~1e-16)."""

    def __init__(self, model: "BranchModel", dt: float, params, input_range):
        nm, nh = model.n_centre, model.n_halfwidth
        nc = nm + nh
        self._setup(model, dt, (("first", 0), ("u1", 0), ("direction", 0), ("xi", 0), ("xi_reversal", 0),
                                ("memory", nc), ("centre_bases", nm), ("halfwidth_bases", nh), ("row", nc)))
        vec, rng = model._step_setup(params, stepper_input_range(model, input_range))
        self._args = model.step_arguments(vec, rng)  # coef, offset, x_lo, x_hi, square, n_centre, kind, n_half
        self._work = np.zeros(3 * nc)
        self.reset()

    def _rest(self) -> np.ndarray:
        rest = np.zeros(self._state.size)
        rest[0], rest[2] = 1.0, 1.0  # before the first sample; rising (s(0) = +1)
        return rest

    def _valid(self, array: np.ndarray) -> bool:
        return bool(np.all(np.isfinite(array)) and abs(array[2]) == 1.0)

    def _advance(self, u: float) -> float:
        coef, offset, x_lo, x_hi, square, nm, kind, nh = self._args
        return branch_advance(u, self._state, coef, offset, x_lo, x_hi, square, kind, nm, nh, self._work)


@njit(cache=True, nogil=True)
def branch_inverse_sample(yd, u_given, k, state, coef, offset, x_lo, x_hi, square, kind, n_centre, n_half, work,
                          limits, st):
    """One sample of the causal inverse (``inverse.search_next``, derivative-free) for the desired
    output yd, or with a non-empty ``u_given`` the forward model at u_given[k]: (u, y), the state
    (``branch_advance``'s layout, u(k-1) at state[1]) committed by ``branch_advance``;
    limits = [u_lo, u_hi, max_step, n_grid, tol, clip_tol]."""
    jump, G_prev, K_prev, prev_row, G, K, jump_c, row = state_views(state, work, n_centre, n_half)
    first = state[0] != 0.0
    x = search_start(st, u_given, k, state[1], limits[0], limits[1], limits[2], int(limits[3]), limits[4],
                     limits[5])
    while not search_done(st):
        y = branch_candidate(x, first, state[1], int(state[2]), state[3], state[4], jump, G_prev, K_prev, prev_row,
                             coef, offset, x_lo, x_hi, square, kind, G, K, jump_c, row)[0]
        x = search_next(st, y - yd, np.nan)
    return x, branch_advance(x, state, coef, offset, x_lo, x_hi, square, kind, n_centre, n_half, work)


@njit(cache=True)
def branch_steps(yd, u_given, coef, offset, x_lo, x_hi, square, n_centre, kind, n_half, u_limit_lo, u_limit_hi,
                 u_start, max_step, n_grid, tol, clip_tol):
    """(u, clipped, y): the causal inverse for desired outputs yd, or, with a non-empty ``u_given``,
    the forward model through the same steps (``branch_inverse_sample`` per sample)."""
    n = u_given.shape[0] if u_given.shape[0] > 0 else yd.shape[0]
    u_out, y_out, clipped = np.empty(n), np.empty(n), np.zeros(n, dtype=np.bool_)
    nc = n_centre + n_half
    state = np.zeros(STATE_HEAD + 3 * nc)
    state[0], state[1], state[2] = 1.0, u_start, 1.0  # before the first sample; rising (s(0) = +1)
    work = np.zeros(3 * nc)
    st = np.empty(SEARCH_SIZE)
    limits = np.array([u_limit_lo, u_limit_hi, max_step, float(n_grid), tol, clip_tol])
    for k in range(n):
        u_out[k], y_out[k] = branch_inverse_sample(yd[k] if yd.shape[0] > 0 else 0.0, u_given, k, state, coef, offset,
                                                   x_lo, x_hi, square, kind, n_centre, n_half, work, limits, st)
        clipped[k] = search_clipped(st)
    return u_out, clipped, y_out


class BranchInverseStepper(KernelInverseStepper):
    """The constant-time inverse stepper of the branch models: ``BranchStepper``'s state (u(k-1) in it)
    and n_clipped; each step is ``branch_inverse_sample``, the per-sample search ``branch_steps`` runs."""

    def __init__(self, model: "BranchModel", dt: float, vec, input_range, a, clip_tol: float):
        nm, nh = model.n_centre, model.n_halfwidth
        nc = nm + nh
        self._setup(model, dt, (("first", 0), ("u1", 0), ("direction", 0), ("xi", 0), ("xi_reversal", 0),
                                ("memory", nc), ("centre_bases", nm), ("halfwidth_bases", nh), ("row", nc)))
        self._args = model.step_arguments(vec, input_range)  # coef, offset, x_lo, x_hi, square, n_centre, kind, n_half
        self._work = np.zeros(3 * nc)
        self._inverse_setup(a, clip_tol)
        self._none = np.zeros(0)
        self.reset()

    def _rest(self) -> np.ndarray:
        rest = np.zeros(self._state.size)
        rest[0], rest[1], rest[2] = 1.0, self.u_start, 1.0
        return rest

    def _valid(self, array: np.ndarray) -> bool:
        return bool(np.all(np.isfinite(array)) and abs(array[2]) == 1.0)

    def _search(self, y_ref: float) -> float:
        coef, offset, x_lo, x_hi, square, nm, kind, nh = self._args
        return branch_inverse_sample(y_ref, self._none, 0, self._state, coef, offset, x_lo, x_hi, square, kind, nm, nh,
                                     self._work, self._limits, self._search_state)[0]


# --- the shared model class ---------------------------------------------------
COEF_BOUND = 10.0  # |coefficient| <= COEF_BOUND * y (basis functions are O(1) on [-1, 1])


class BranchModel(KernelInvertible, HysteresisModel):
    """Base of ``elliptical`` and ``dual-polynomial``: every parameter is linear.

    Subclasses define the centre-line and half-width parameters and bases.
    Parameter order: centre coefficients, half-width coefficients, offset.
    """

    def __init__(self, offset: bool = True):
        self.offset = check_bool(self.name, "offset", offset)

    # subclasses -----------------------------------------------------------
    def _centre_parameters(self) -> list[tuple[str, str]]:
        raise NotImplementedError

    def _halfwidth_parameters(self) -> list[tuple[str, str]]:
        raise NotImplementedError

    def _linearised(self, u: np.ndarray) -> np.ndarray:
        """The input on which the loop is drawn (identity unless overridden)."""
        return u

    halfwidth_kind = POLYNOMIAL  # the half-width basis (``branch_basis``)

    @property
    def n_centre(self) -> int:
        return len(self._centre_parameters())

    @property
    def n_halfwidth(self) -> int:
        return len(self._halfwidth_parameters())

    @property
    def square_input(self) -> bool:
        """The loop is drawn on u |u| (``_linearised``) rather than on u."""
        return False

    # interface ------------------------------------------------------------
    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        b = COEF_BOUND * scale.y
        params = [Parameter(n, 0.0, -b, b, True, d, unit="y") for n, d in self._centre_parameters()]
        params += [Parameter(n, 0.0, -b, b, True, d, unit="y") for n, d in self._halfwidth_parameters()]
        if self.offset:
            params.append(self.offset_parameter(scale))
        return params

    def normalised(self, u, input_range=None) -> np.ndarray:
        """xi: the (linearised) input mapped to [-1, 1] over ``input_range``."""
        u = np.ascontiguousarray(u, dtype=float)
        lo, hi = self._input_range(u, input_range)
        if not hi > lo:
            raise ModelError(
                f"model {self.name!r} needs an input that varies (or an input_range of positive width), "
                f"got range ({lo!r}, {hi!r})"
            )
        x_lo, x_hi = self._linearised(np.array([lo, hi]))
        return normalised_input(self._linearised(u), float(x_lo), float(x_hi))

    def regressors(self, u, dt: float, nonlinear=None, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        if nonlinear:
            raise ModelError(
                f"model {self.name!r} has no nonlinear parameters; got {sorted(nonlinear)}"
            )
        xi = self.normalised(u, input_range)
        Phi = branch_regressors(xi, direction(u), self.n_centre, self.halfwidth_kind, self.n_halfwidth)
        if self.offset:
            Phi = np.concatenate((Phi, np.ones((u.size, 1))), axis=1)
        return Phi

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        P = self._check_param_sets(param_sets)
        Phi = self.regressors(u, dt, None, input_range)
        # the time loop is input-only (in branch_regressors); the parameter sets are one product
        return P @ Phi.T

    def stepper(self, dt: float, params, input_range=None) -> BranchStepper:
        """A constant-time ``BranchStepper`` (the per-sample rule of ``branch_regressors``)."""
        self._check_causal()
        return BranchStepper(self, dt, params, input_range)

    # inverse (``KernelInvertible``) ---------------------------------------
    step_kernel = staticmethod(branch_steps)
    inverse_stepper_class = BranchInverseStepper

    def step_arguments(self, vector, input_range) -> tuple:
        x_lo, x_hi = self._linearised(np.array(input_range))
        coef = np.ascontiguousarray(vector[: self.n_centre + self.n_halfwidth])
        return (coef, float(vector[-1]) if self.offset else 0.0, float(x_lo), float(x_hi), self.square_input,
                self.n_centre, self.halfwidth_kind, self.n_halfwidth)
