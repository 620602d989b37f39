"""Constant-time steppers of the P-I family (classical-pi, mrpim, rate-dependent-pi and the mrpim
extensions that have a step structure: +relaxation, +creep, +interference).

Each step is one call of a jitted function with four or five arguments: the model's constants
packed in one array and its state in another (numba unboxes few arguments quickly, which keeps a
Python ``step`` call near a microsecond). The update is ``inverse.step_commit`` (forward) and
``inverse.invert_sample`` (inverse), i.e. ``kernels.pi_sample``: the per-sample code the batch
kernel, the batch inverse and the exported C share.

Packed constants: [dt, g_lo, g_hi, q, r_lo (n), r_hi (n), weights (n), poly (m), fa, fb0, fb1, fw (f each)].
Packed state: [first (1.0 before the first sample), u(k-1), u(k-2), k, W_1..W_n, x_1..x_f].
A time-varying offset (creep, interference) is computed by the model (``varying_base``) for a
block of ``BASE_BLOCK`` samples at a time, the block holding the current sample: the memory is
fixed and the cost per step constant however long the stepper runs.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .errors import ModelError
from .kernels import KERNEL_FASTMATH
from .inverse import (DEFAULT_GRID, DEFAULT_GUIDE_TIME, InverseArguments, StepInvertible, StepStructure,
                      check_guide_time, guide_rate, guide_step, guided_invert_sample, invert_sample, step_commit)
from .root_search import SEARCH_SIZE, search_clipped
from .stepper import InverseStepper, Stepper, check_state_keys, check_step_input

HEAD = 4  # dt, g_lo, g_hi, q  /  first, u1, u2, k
BASE_BLOCK = 1024  # samples of a time-varying offset computed at once


@njit(inline="always")
def _unpack(coef, n, m, f):
    o = HEAD
    r_lo = coef[o:o + n]
    r_hi = coef[o + n:o + 2 * n]
    weights = coef[o + 2 * n:o + 3 * n]
    o += 3 * n
    poly = coef[o:o + m]
    o += m
    return r_lo, r_hi, weights, poly, coef[o:o + f], coef[o + f:o + 2 * f], coef[o + 2 * f:o + 3 * f], \
        coef[o + 3 * f:o + 4 * f]


@njit(inline="always")
def _advance(state, u):
    state[2] = u if state[0] != 0.0 else state[1]
    state[1] = u
    state[0] = 0.0
    state[3] += 1.0


@njit(inline="always")
def _views(coef, state, fpow):
    """The parameter arrays in ``coef`` and the state's plays and filters, as views (sizes from the arrays)."""
    f = fpow.shape[0]
    n = state.shape[0] - HEAD - f
    m = coef.shape[0] - HEAD - 3 * n - 4 * f
    return _unpack(coef, n, m, f) + (state[HEAD:HEAD + n], state[HEAD + n:HEAD + n + f])


@njit(cache=True, nogil=True, fastmath=KERNEL_FASTMATH)
def pi_step(u, base, coef, state, fpow):
    """The output at this sample for input u (the state advances); sizes from the arrays."""
    r_lo, r_hi, weights, poly, fa, fb0, fb1, fw, w, xf = _views(coef, state, fpow)
    y = step_commit(u, state[0] != 0.0, state[1], state[2], coef[0], base, w, xf, r_lo, r_hi, coef[1], coef[2],
                    weights, poly, coef[3], fa, fb0, fb1, fpow, fw)
    _advance(state, u)
    return y


@njit(cache=True, nogil=True, fastmath=KERNEL_FASTMATH)
def pi_inverse_step(yd, base, coef, state, fpow, limits, st):
    """The input for desired output yd at this sample (the state advances); limits = [u_lo, u_hi,
    max_step, n_grid, tol]; ``search_clipped(st)`` tells whether it clipped."""
    r_lo, r_hi, weights, poly, fa, fb0, fb1, fw, w, xf = _views(coef, state, fpow)
    x = invert_sample(yd, state[0] != 0.0, state[1], state[2], coef[0], base, limits[0], limits[1], limits[2],
                      int(limits[3]), limits[4], st, w, xf, r_lo, r_hi, coef[1], coef[2], weights, poly, coef[3],
                      fa, fb0, fb1, fpow, fw)
    _advance(state, x)
    return x


@njit(cache=True, nogil=True, fastmath=KERNEL_FASTMATH)
def pi_guided_inverse_step(yd, mapped, base, coef, state, fpow, limits, st, guide):
    """The reference-driven inverse at this sample (``inverse.guided_invert_sample``): the input for
    desired output yd, the mapped reference ``mapped`` (``inverse.mapped_reference``) giving the guide
    (``inverse.guide_step``; limits[5] its follower's c); guide = [g(k-1), g(k-2)] and the state advance."""
    r_lo, r_hi, weights, poly, fa, fb0, fb1, fw, w, xg = _views(coef, state, fpow)
    first = state[0] != 0.0
    if first:
        guide[0] = guide[1] = mapped
    g = guide_step(mapped, guide[0], guide[1], limits[2], limits[5])
    x = guided_invert_sample(yd, g, first, state[1], guide[0], guide[1], coef[0], base, limits[0], limits[1],
                             limits[2], int(limits[3]), limits[4], st, w, xg, r_lo, r_hi, coef[1], coef[2], weights,
                             poly, coef[3], fa, fb0, fb1, fpow, fw)
    guide[1] = g if first else guide[0]
    guide[0] = g
    _advance(state, x)
    return x


def pack_structure(s: StepStructure, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """(constants, fpow) of a step structure, in ``pi_step``'s layout."""
    r_lo, r_hi, g_lo, g_hi, weights, poly, q, fa, fb0, fb1, fpow, fw = s.arguments()
    coef = np.concatenate(([float(dt), g_lo, g_hi, q], r_lo, r_hi, weights, poly, fa, fb0, fb1, fw))
    return np.ascontiguousarray(coef), np.ascontiguousarray(fpow)


class _PIBase:
    """What the forward and inverse steppers share: the structure, the state, the offset."""

    def _setup(self, model, dt: float, params, input_range):
        if input_range is None:
            raise ModelError(f"model {model.name!r}: a stepper needs the input range that fixes the play "
                             "thresholds (the fit's input_range)")
        self.model = model
        self.dt = float(dt)
        if not (self.dt > 0 and np.isfinite(self.dt)):
            raise ModelError(f"model {model.name!r}: time step must be positive, got {dt!r}")
        self.input_range = tuple(map(float, input_range))
        self.params = model.unpack(model.pack(params) if isinstance(params, dict) else params)
        self._varying = bool(getattr(model, "time_varying_base", False))
        s = model._structure(self.dt, self.params, self.input_range, BASE_BLOCK if self._varying else 1)
        self.structure = s
        self._coef, self._fpow = pack_structure(s, self.dt)
        self._n, self._f = s.r_lo.size, self._fpow.size
        self._base = np.array(s.base, dtype=float)  # the offset at samples _base_start .. + BASE_BLOCK - 1
        self._base_start = 0
        self._base0 = float(self._base[0])
        if self._varying:  # the base model's own (constant) offset, without creep and interference
            base_names = getattr(model, "base_names", ())
            self._offset = model.base_model.step_structure(
                self.dt, {k: self.params[k] for k in base_names}, self.input_range, BASE_BLOCK).base
        self._state = np.zeros(HEAD + self._n + self._f)

    def _base_at(self, k: int) -> float:
        if not self._varying:
            return self._base0
        i = k - self._base_start
        if not 0 <= i < BASE_BLOCK:  # the next block, in fixed memory
            self._base_start, i = k, 0
            self._base = self.model.varying_base(self._offset, np.arange(k, k + BASE_BLOCK, dtype=np.int64),
                                                 self.dt, self.params)
        return float(self._base[i])

    def _start(self, u_before: float) -> None:
        self._state[:] = 0.0
        self._state[0] = 1.0
        self._state[1] = self._state[2] = u_before

    def _keys(self):
        return ("first", "u1", "u2", "k", "plays", "filters")

    @property
    def state(self) -> dict:
        st = self._state
        return {"first": bool(st[0] != 0.0), "u1": float(st[1]), "u2": float(st[2]), "k": int(st[3]),
                "plays": [float(v) for v in st[HEAD:HEAD + self._n]],
                "filters": [float(v) for v in st[HEAD + self._n:]]}

    def set_state(self, state: dict) -> None:
        state = check_state_keys(self.model.name, state, _PIBase._keys(self))
        plays, filters = list(state["plays"]), list(state["filters"])
        if len(plays) != self._n or len(filters) != self._f:
            raise ModelError(f"{self.model.name}: the state holds {len(plays)} plays and {len(filters)} filters, "
                             f"this model {self._n} and {self._f}")
        new = np.array([1.0 if state["first"] else 0.0, float(state["u1"]), float(state["u2"]), int(state["k"]),
                        *map(float, plays), *map(float, filters)])
        if not np.all(np.isfinite(new)) or new[3] < 0:
            raise ModelError(f"{self.model.name}: a state holds non-finite values or a negative sample count")
        self._state[:] = new


class PIStepper(_PIBase, Stepper):
    """The causal stepper of a P-I-family model (module docstring)."""

    def __init__(self, model, dt: float, params, input_range):
        self._setup(model, dt, params, input_range)
        self.reset()

    def reset(self) -> None:
        self._start(0.0)

    def step(self, u: float) -> float:
        u = float(u)
        if u - u != 0.0:  # NaN or inf (cheaper than math.isfinite on a hot path)
            check_step_input(self.model.name, u)
        base = self._base0 if not self._varying else self._base_at(int(self._state[3]))
        return pi_step(u, base, self._coef, self._state, self._fpow)


class PIInverseStepper(_PIBase, InverseStepper):
    """The causal inverse stepper of a P-I-family model: ``step(y_ref) -> u``, equal to the batch
    ``invert`` given the same options (``reference_scale``: the |y| the reach tolerance
    1e-12 (1 + scale) is relative to; the batch inverse takes max |y_d| of its reference).
    ``inverse``, ``guide_time`` as ``invert`` (``inverse.INVERSES``); ``self.inverse`` names the one that runs.
    The reference-driven inverse's state adds "guide": [y_ref(0), g(k-1), g(k-2)] (its filter
    slots hold the guide's filters)."""

    def __init__(self, model, dt: float, params, input_range, input_limits=None, n_grid: int = DEFAULT_GRID,
                 max_rate: float | None = None, u_start: float | None = None,
                 reference_scale: float | None = None, inverse: str = "auto",
                 guide_time: float = DEFAULT_GUIDE_TIME):
        self._setup(model, dt, params, input_range)
        scale = abs(float(reference_scale)) if reference_scale is not None else 0.0
        a = InverseArguments.check(model.name, [scale], dt, self.input_range, input_limits, n_grid, max_rate,
                                   u_start)
        self.inverse, gain = model.resolve_inverse(inverse, self.structure, self.input_range)
        self._inv_gain = 1.0 / gain if self.inverse != "exact" else 0.0
        self.input_limits = (a.lo, a.hi)
        self.u_start = a.u_start
        self.guide_time = check_guide_time(model.name, guide_time)
        self._limits = np.array([a.lo, a.hi, a.max_step, float(a.n_grid), a.tol, guide_rate(self.dt, self.guide_time)])
        self._search = np.empty(SEARCH_SIZE)
        self._guide = np.zeros(2)
        self._y_first = 0.0
        self.reset()

    def reset(self) -> None:
        self._start(self.u_start)
        self._guide[:] = self.u_start
        self._y_first = 0.0
        self.clipped = False
        self.n_clipped = 0

    def step(self, y_ref: float) -> float:
        y_ref = float(y_ref)
        if y_ref - y_ref != 0.0:
            check_step_input(self.model.name, y_ref)
        base = self._base0 if not self._varying else self._base_at(int(self._state[3]))
        if self.inverse == "exact":
            u = pi_inverse_step(y_ref, base, self._coef, self._state, self._fpow, self._limits, self._search)
        else:
            if self._state[0] != 0.0:
                self._y_first = y_ref
            mapped = self.u_start + (y_ref - self._y_first) * self._inv_gain  # as inverse.mapped_reference
            u = pi_guided_inverse_step(y_ref, mapped, base, self._coef, self._state, self._fpow, self._limits,
                                       self._search, self._guide)
        self.clipped = bool(search_clipped(self._search))
        self.n_clipped += self.clipped
        return u

    def _keys(self):
        return super()._keys() + ("n_clipped",) + (("guide",) if self.inverse != "exact" else ())

    @property
    def state(self) -> dict:
        extra = {"guide": [self._y_first, float(self._guide[0]), float(self._guide[1])]} \
            if self.inverse != "exact" else {}
        return dict(super().state, n_clipped=int(self.n_clipped), **extra)

    def set_state(self, state: dict) -> None:
        check_state_keys(self.model.name, state, self._keys())
        guide = None
        if self.inverse != "exact":
            guide = [float(v) for v in state["guide"]]
            if len(guide) != 3 or not np.all(np.isfinite(guide)):
                raise ModelError(f"{self.model.name}: a reference-driven inverse's state needs a finite guide "
                                 "[y_ref(0), g(k-1), g(k-2)]")
        super().set_state({k: v for k, v in state.items() if k not in ("n_clipped", "guide")})
        self.n_clipped = int(state["n_clipped"])
        if guide is not None:
            self._y_first = guide[0]
            self._guide[:] = guide[1:]


class SteppableStructure(StepInvertible):
    """A model with a step structure (``StepInvertible``) that also steps: the mixin of the P-I family."""

    #: whether the step structure's offset changes with time (creep, interference)
    time_varying_base = False

    def stepper(self, dt: float, params, input_range=None):
        """A constant-time ``PIStepper`` (models/pi_stepper.py) where the model has a step structure;
        else the base class's replay stepper (the extended models override this: extended_stepper.py)."""
        self._check_causal()
        if self.inverse_unavailable:
            return super().stepper(dt, params, input_range)
        return PIStepper(self, dt, params, input_range)

    def inverse_stepper(self, dt: float, params, input_range=None, input_limits=None, **options):
        """The causal inverse one sample at a time (``PIInverseStepper``); options as ``invert``
        (n_grid, max_rate, u_start, inverse, guide_time) and ``reference_scale``."""
        reason = self.inverse_unavailable
        if reason:
            raise ModelError(f"model {self.name!r} cannot be inverted: {reason}")
        return PIInverseStepper(self, dt, params, input_range, input_limits, **options)

