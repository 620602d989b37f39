"""Discrete Preisach model (registry name ``preisach``).

Mayergoyz, "Mathematical Models of Hysteresis" (Springer, 1991), ch. 1: the
output is a weighted superposition of relay hysterons gamma_{alpha,beta}
(alpha >= beta) over the Preisach triangle; discretised on a grid of cells
with one relay per cell and a weight mu >= 0 per relay:

    y(k) = c + sum_{i >= j} w_ij R_ij(k)
    R_ij(k) = +1 if u(k) >= alpha_i;  -1 if u(k) <= beta_j;  R_ij(k-1) otherwise
    R_ij(-1) = -1                                   (negative saturation)

Grid (hyperparameter ``grid_size`` M): the input range (u_min, u_max) is cut
into M equal cells with centres L_m = u_min + (m + 1/2)(u_max - u_min)/M,
m = 0..M-1; alpha_i = L_i, beta_j = L_j, for every i >= j: M(M+1)/2 relays.
The diagonal relays (alpha = beta) switch without hysteresis and carry the
reversible part. (u_min, u_max) is ``input_range`` (None: the input's own
range), so piezo data at +-150 V and the DEA at 0.5-2.5 kV get the same grid
in relative terms.

Initial state: every relay at -1, as if the input had come up from below the
range; the paper's drive starts at its minimum, where this is exact.

The model is linear in its weights and offset (``regressors`` returns the
relay states and a column of ones); the weights have lower bound 0 (a Preisach
density is non-negative), so the exact solve is a non-negative least squares
(scipy.optimize.nnls / lsq_linear with these bounds). Non-negative weights
give the wiping-out and congruency properties of the Preisach model; the model
is rate-independent.

Inverse (``KernelInvertible.invert``, kernel ``preisach_steps``; ``preisach_step`` applies
the relay rule ``relay_switch`` of the forward model): at each sample the output is a
staircase in u, flat between switching levels, jumping where u crosses one (up above the
previous input with non-negative weights, down below it). The search walks out from u(k-1):
an output on a stair is met exactly (the previous input is kept while y_d stays on its
stair); one between two stairs is bracketed by the jump, narrowed to the switching level,
and the nearer stair is taken (a miss of at most half that jump, not counted as clipped; a
stair reached only at a level exactly, u = alpha, is such a case). Clipped and counted only
where y_d is out of reach of every stair within the limits by more than half the largest
stair (``largest_stair``: the staircase's resolution). Negative weights (outside the
default bounds) make the stairs non-monotone; the walk then takes the first bracket from
u(k-1) or the nearest stair it visits.
"""

from __future__ import annotations

import numpy as np
from numba import njit, prange

from .base import DataScale, HysteresisModel, Parameter
from .errors import ModelError
from .hyperparameters import check_bool, check_int
from .inverse import KernelInverseStepper, KernelInvertible
from .root_search import SEARCH_SIZE, search_clipped, search_done, search_next, search_start
from .stepper import ArrayStepper, stepper_input_range

WEIGHT_BOUND = 2.0  # 0 <= w_ij <= WEIGHT_BOUND * y


@njit(cache=True, nogil=True)
def relay_switch(state, uk, alpha, beta):
    """A relay's state after input uk: +1 at or above alpha, -1 at or below beta, else held."""
    if uk >= alpha:
        return 1
    if uk <= beta:
        return -1
    return state


@njit(cache=True)
def relay_states(u, alphas, betas):
    """States (T, n_relays) in {-1, +1} as int8, from all relays at -1."""
    n_t = u.shape[0]
    n_r = alphas.shape[0]
    out = np.empty((n_t, n_r), dtype=np.int8)
    state = -np.ones(n_r, dtype=np.int8)
    for k in range(n_t):
        for i in range(n_r):
            state[i] = relay_switch(state[i], u[k], alphas[i], betas[i])
            out[k, i] = state[i]
    return out


@njit(cache=True)
def _switches(u, alphas, betas, ev_k, ev_i, ev_s, record):
    """Walk the relays through u; count switches, and store them if ``record``."""
    n_r = alphas.shape[0]
    state = -np.ones(n_r, dtype=np.int8)
    count = 0
    for k in range(u.shape[0]):
        for i in range(n_r):
            new = relay_switch(state[i], u[k], alphas[i], betas[i])
            if new != state[i]:
                state[i] = new
                if record:
                    ev_k[count] = k
                    ev_i[count] = i
                    ev_s[count] = new
                count += 1
    return count


@njit(cache=True)
def relay_events(u, alphas, betas):
    """Switching events (sample index, relay, new state), in time order."""
    ev_k = np.empty(0, dtype=np.int64)
    ev_i = np.empty(0, dtype=np.int64)
    ev_s = np.empty(0, dtype=np.int8)
    total = _switches(u, alphas, betas, ev_k, ev_i, ev_s, False)
    ev_k = np.empty(total, dtype=np.int64)
    ev_i = np.empty(total, dtype=np.int64)
    ev_s = np.empty(total, dtype=np.int8)
    _switches(u, alphas, betas, ev_k, ev_i, ev_s, True)
    return ev_k, ev_i, ev_s


@njit(cache=True, parallel=True)
def preisach_batch(n_t, ev_k, ev_i, ev_s, weights, offsets):
    """y (B, T) from the switching events, in parallel over parameter sets."""
    n_set = weights.shape[0]
    n_ev = ev_k.shape[0]
    out = np.empty((n_set, n_t))
    for b in prange(n_set):
        acc = 0.0
        for i in range(weights.shape[1]):
            acc -= weights[b, i]
        e = 0
        for k in range(n_t):
            while e < n_ev and ev_k[e] == k:
                acc += 2.0 * weights[b, ev_i[e]] * ev_s[e]
                e += 1
            out[b, k] = offsets[b] + acc
    return out


@njit(cache=True, nogil=True)
def preisach_step(u, state, alphas, betas, weights, acc, commit):
    """sum_i w_i R_i after input u, from the relay states ``state`` whose sum is ``acc`` (switch by
    switch, as ``preisach_batch`` adds its events); the states move to u only if ``commit``."""
    for i in range(alphas.shape[0]):
        new = relay_switch(state[i], u, alphas[i], betas[i])
        if new != state[i]:
            acc += 2.0 * weights[i] * new
            if commit:
                state[i] = new
    return acc


@njit(cache=True, nogil=True)
def preisach_advance(u, state, alphas, betas, weights, relays, offset):
    """One sample of ``PreisachStepper``: the relays (as int8 in ``relays``, mirrored in state[1:1 + n])
    switch to input u by ``preisach_step``, state[0] holds the running sum (as the batch kernel
    adds its switching events). Returns y(k)."""
    acc = preisach_step(u, relays, alphas, betas, weights, state[0], True)
    state[0] = acc
    for i in range(relays.shape[0]):
        state[1 + i] = relays[i]
    return offset + acc


class PreisachStepper(ArrayStepper):
    """The constant-time stepper of ``preisach``: state (the weighted sum, every relay's state);
    each step switches the relays with ``preisach_step`` (``relay_switch``, the batch kernel's rule)
    and adds their switches to the sum in the batch kernel's order."""

    def __init__(self, model: "Preisach", dt: float, params, input_range):
        self._setup(model, dt, (("sum", 0), ("relays", model.n_relays)))
        vec, rng = model._step_setup(params, stepper_input_range(model, input_range))
        self._alphas, self._betas, self._weights, self._offset = model.step_arguments(vec, rng)
        self._relays = np.empty(model.n_relays, dtype=np.int8)
        self.reset()

    def _rest(self) -> np.ndarray:
        acc = 0.0
        for w in self._weights:  # all relays at -1: as preisach_batch starts its sum
            acc -= w
        return np.concatenate(([acc], -np.ones(self.model.n_relays)))

    def reset(self) -> None:
        super().reset()
        self._relays[:] = -1

    def set_state(self, state: dict) -> None:
        super().set_state(state)
        self._relays[:] = self._state[1:].astype(np.int8)

    def _valid(self, array: np.ndarray) -> bool:
        return bool(np.all(np.isfinite(array)) and np.all(np.abs(array[1:]) == 1.0))

    def _advance(self, u: float) -> float:
        return preisach_advance(u, self._state, self._alphas, self._betas, self._weights, self._relays, self._offset)


@njit(cache=True, nogil=True)
def preisach_inverse_sample(yd, u_given, k, state, alphas, betas, weights, relays, offset, limits, st):
    """One sample of the causal inverse (``inverse.search_next``, derivative-free) for the desired
    output yd, or with a non-empty ``u_given`` the forward model at u_given[k]: (u, y), the relays
    committed by ``preisach_advance``. state = [sum, relays (mirrored), u(k-1)]; limits = [u_lo, u_hi,
    max_step, n_grid, tol, clip_tol]."""
    u1 = state[state.shape[0] - 1]
    x = search_start(st, u_given, k, u1, limits[0], limits[1], limits[2], int(limits[3]), limits[4], limits[5])
    while not search_done(st):
        x = search_next(st, offset + preisach_step(x, relays, alphas, betas, weights, state[0], False) - yd, np.nan)
    y = preisach_advance(x, state, alphas, betas, weights, relays, offset)
    state[state.shape[0] - 1] = x
    return x, y


@njit(cache=True)
def preisach_steps(yd, u_given, alphas, betas, weights, offset, u_limit_lo, u_limit_hi, u_start, max_step, n_grid,
                   tol, clip_tol):
    """(u, clipped, y): the causal inverse for desired outputs yd (clipped where the nearest output
    misses by more than ``clip_tol``), or, with a non-empty ``u_given``, the forward model through
    the same steps (``preisach_inverse_sample`` per sample)."""
    n = u_given.shape[0] if u_given.shape[0] > 0 else yd.shape[0]
    u_out, y_out, clipped = np.empty(n), np.empty(n), np.zeros(n, dtype=np.bool_)
    relays = -np.ones(alphas.shape[0], dtype=np.int8)
    state = -np.ones(alphas.shape[0] + 2)
    acc = 0.0
    for i in range(weights.shape[0]):
        acc -= weights[i]
    state[0] = acc
    state[state.shape[0] - 1] = u_start
    st = np.empty(SEARCH_SIZE)
    limits = np.array([u_limit_lo, u_limit_hi, max_step, float(n_grid), tol, clip_tol])
    for k in range(n):
        u_out[k], y_out[k] = preisach_inverse_sample(yd[k] if yd.shape[0] > 0 else 0.0, u_given, k, state, alphas,
                                                     betas, weights, relays, offset, limits, st)
        clipped[k] = search_clipped(st)
    return u_out, clipped, y_out


class PreisachInverseStepper(KernelInverseStepper):
    """The constant-time inverse stepper of ``preisach``: state (the weighted sum, every relay's
    state, u(k-1)) and n_clipped; each step is ``preisach_inverse_sample``, the per-sample search
    ``preisach_steps`` runs."""

    def __init__(self, model: "Preisach", dt: float, vec, input_range, a, clip_tol: float):
        self._setup(model, dt, (("sum", 0), ("relays", model.n_relays), ("u1", 0)))
        self._alphas, self._betas, self._weights, self._offset = model.step_arguments(vec, input_range)
        self._relays = np.empty(model.n_relays, dtype=np.int8)
        self._inverse_setup(a, clip_tol)
        self._none = np.zeros(0)
        self.reset()

    def _rest(self) -> np.ndarray:
        acc = 0.0
        for w in self._weights:  # all relays at -1: as preisach_batch starts its sum
            acc -= w
        return np.concatenate(([acc], -np.ones(self.model.n_relays), [self.u_start]))

    def reset(self) -> None:
        super().reset()
        self._relays[:] = -1

    def set_state(self, state: dict) -> None:
        super().set_state(state)
        self._relays[:] = self._state[1:-1].astype(np.int8)

    def _valid(self, array: np.ndarray) -> bool:
        return bool(np.all(np.isfinite(array)) and np.all(np.abs(array[1:-1]) == 1.0))

    def _search(self, y_ref: float) -> float:
        return preisach_inverse_sample(y_ref, self._none, 0, self._state, self._alphas, self._betas, self._weights,
                                       self._relays, self._offset, self._limits, self._search_state)[0]


class Preisach(KernelInvertible, HysteresisModel):
    """Discrete Preisach model on a triangular relay grid; see the module docstring."""

    name = "preisach"

    def __init__(self, grid_size: int = 10, offset: bool = True):
        self.grid_size = check_int(self.name, "grid_size", grid_size, 1, 100)
        self.offset = check_bool(self.name, "offset", offset)
        self._index = [(i, j) for i in range(self.grid_size) for j in range(i + 1)]

    @property
    def n_relays(self) -> int:
        return len(self._index)

    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        b = WEIGHT_BOUND * scale.y
        params = [
            Parameter(f"w{i + 1}_{j + 1}", 0.0, 0.0, b, True,
                      f"weight of the relay up at level {i + 1}, down at level {j + 1} (>= 0)", unit="y")
            for i, j in self._index
        ]
        if self.offset:
            params.append(self.offset_parameter(scale))
        return params

    def grid(self, u, input_range=None) -> tuple[np.ndarray, np.ndarray]:
        """(alphas, betas) of the relays, in parameter order."""
        lo, hi = self._input_range(np.asarray(u, dtype=float), input_range)
        if not hi > lo:
            raise ModelError(
                f"model {self.name!r} needs an input that varies (or an input_range of positive width), "
                f"got range ({lo!r}, {hi!r})"
            )
        levels = lo + (np.arange(self.grid_size) + 0.5) * (hi - lo) / self.grid_size
        idx = np.array(self._index)
        return levels[idx[:, 0]].copy(), levels[idx[:, 1]].copy()

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        alphas, betas = self.grid(u, input_range)
        ev_k, ev_i, ev_s = relay_events(u, alphas, betas)
        weights = np.ascontiguousarray(P[:, : self.n_relays])
        offsets = np.ascontiguousarray(P[:, -1]) if self.offset else np.zeros(P.shape[0])
        return preisach_batch(u.size, ev_k, ev_i, ev_s, weights, offsets)

    def regressors(self, u, dt: float, nonlinear=None, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        if nonlinear:
            raise ModelError(f"model {self.name!r} has no nonlinear parameters; got {sorted(nonlinear)}")
        alphas, betas = self.grid(u, input_range)
        Phi = relay_states(u, alphas, betas).astype(float)
        if self.offset:
            Phi = np.concatenate((Phi, np.ones((u.size, 1))), axis=1)
        return Phi

    def stepper(self, dt: float, params, input_range=None) -> PreisachStepper:
        """A constant-time ``PreisachStepper`` (the batch kernel's relay rule per sample)."""
        self._check_causal()
        return PreisachStepper(self, dt, params, input_range)

    # inverse (``KernelInvertible``) ---------------------------------------
    step_kernel = staticmethod(preisach_steps)
    inverse_stepper_class = PreisachInverseStepper

    def step_arguments(self, vector, input_range) -> tuple:
        alphas, betas = self.grid(np.zeros(1), input_range)
        return alphas, betas, np.ascontiguousarray(vector[: self.n_relays]), float(vector[-1]) if self.offset else 0.0

    def largest_stair(self, params, input_range) -> float:
        """The largest jump of the staircase: 2 x the largest total weight of the relays that
        share a switching level (up or down)."""
        vec, rng = self._step_setup(params, input_range)
        alphas, betas, w, _ = self.step_arguments(vec, rng)
        sums = [np.bincount(np.unique(v, return_inverse=True)[1], weights=w) for v in (alphas, betas)]
        return 2.0 * float(max(np.max(np.abs(s)) for s in sums))

    def clip_tolerance(self, vector, input_range, tol) -> float:
        """Half the largest stair: the staircase's resolution (module docstring)."""
        return 0.5 * self.largest_stair(vector, input_range) + tol
