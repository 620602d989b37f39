"""``viscoelastic``: the virtual DEA's physics as a benchmark model.

The lumped planar DEA of ``hysbench.data.virtual_dea`` (equations in its docstring):
Gent spring + K Gent-Maxwell branches (Zhao-Koh-Suo flow rule) + parallel dashpot,
ideal dielectric, platform force balance; the same numba kernel
(``hysbench.models.dea_physics``) simulates the data and this model.

    y(t) = length * (lam_a(t) - lam0) + offset

Identified parameters (2K + 2 nonlinear, 2 linear):

    mu, eta_v              Gent spring modulus (kPa), parallel dashpot viscosity (kPa s)
    mu1..muK, tau1..tauK   branch moduli (kPa) and relaxation times (s)
    length   (linear)      unstretched length of the active region (output units per unit stretch;
                           mm for a mm output)
    offset   (linear)      output offset (sensor zero)

The output is exactly linear in ``length`` because the force balance depends on the
two regions' lengths only through their ratio, a hyperparameter (``length_ratio`` =
L_passive / L_active). Fixed as hyperparameters: the Gent limit J, the prestretch,
the thickness, eps_r and the input's unit: they are the device's geometry and material
constants, and the moduli trade off against them exactly (all stresses scale together
with eps_r / H^2), so fitting them too would leave the fit undetermined.

Default bounds scale with the data: stresses with S = s_M(u_max) * length0 / y_max, the
stiffness per unit stretch that turns the Maxwell stress at the largest input,
s_M = eps (u_max / H)^2 lam0 lam_t^2, into the largest output; times with the shortest
period. ``input_range`` is accepted and ignored (no input-dependent structure).
``simulate`` and ``simulate_batch`` integrate every sample interval with RK4 (exactly the data
generator's computation). The windowed forms the identifiers call (``simulate_window_batch``,
``windowed_regressors[_batch]``) cross the warm-up before the window with RK4 steps of up to
``warmup_stride`` samples (5 ms at 1 ms sampling, within RK4's stability limit): on the
virtual DEA's records that changes the window's output by about 2e-7 of its peak-to-peak and
cuts the cost of an evaluation about four times; ``warmup_stride=1`` is exact.
Parameter sets the actuator cannot sustain (a Gent lock-up, a loss of stability) give
NaN from the sample where that happens: identifiers must treat NaN as infeasible.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from . import dea_physics
from .dea_physics import TRUTH

from .base import DataScale, HysteresisModel, Parameter
from .errors import ModelError
from .hyperparameters import check_bool, check_int, check_number
from .inverse import InverseArguments, Inversion
from .stepper import ArrayInverseStepper, ArrayStepper


def _physics_setup(stepper, model: "Viscoelastic", dt: float, params) -> int:
    """The state layout and the fitted physics of a viscoelastic stepper (forward or inverse); returns
    the physics state's length."""
    n = 1 + 4 * model.n_branches
    stepper._setup(model, dt, (("first", 0), ("u1_kv", 0), ("substeps", 0), ("failed", 0), ("physics", n)))
    P = model._check_param_sets(model.pack(params) if isinstance(params, Mapping) else params)
    K = model.n_branches
    stepper._phys = np.ascontiguousarray(model.physical_vectors(P)[0])
    stepper._length = float(P[0, 2 + 2 * K])
    stepper._offset = float(P[0, 3 + 2 * K]) if model.offset else 0.0
    stepper._kv = model.volts_per_input_unit / 1000.0
    stepper._inv_6tau = dea_physics._inv_6tau(stepper._phys, K)
    return n


class ViscoelasticStepper(ArrayStepper):
    """The constant-time stepper of ``viscoelastic``: state (first, the previous input in kV, the RK4
    substeps per sample, failed, the physics state); each step integrates one sample interval with
    ``dea_physics.stepper_sample`` (the batch kernel's ``_advance``). ``input_range`` is not needed
    (the model has no input-dependent structure)."""

    def __init__(self, model: "Viscoelastic", dt: float, params):
        n = _physics_setup(self, model, dt, params)
        self._work = np.empty((5, n))
        self._head, self._x = self._state[:4], self._state[4:]  # views: the state array is updated in place
        self.reset()

    def _rest(self) -> np.ndarray:
        return np.concatenate(([1.0, 0.0, 1.0, 0.0], dea_physics.initial_state(self._phys, self.model.n_branches)))

    def _valid(self, array: np.ndarray) -> bool:
        head_ok = bool(np.all(np.isfinite(array[:4])) and array[2] >= 1 and array[2] == int(array[2]))
        return head_ok and (array[3] != 0.0 or bool(np.all(np.isfinite(array[4:]))))

    def _advance(self, u: float) -> float:
        dlam = dea_physics.stepper_sample(u * self._kv, self.dt, self._phys, self.model.n_branches, self._x,
                                          self._head, self._inv_6tau, self._work)
        return self._length * dlam + self._offset

class ViscoelasticInverseStepper(ArrayInverseStepper):
    """The constant-time inverse stepper of ``viscoelastic``: ``step(y_ref) -> u``, the batch ``invert``'s
    root search for one sample (``dea_physics.inverse_stepper_sample``, the per-sample function of
    ``invert_stretch``). State (first, the previous input in kV, the RK4 substeps per sample, failed,
    the physics state) and ``n_clipped``. ``reference_scale``: the largest |y_ref - offset| the
    references reach (the batch inverse takes it from its whole reference); the reach tolerance is
    1e-12 (1 + reference_scale / length), as the batch inverse's."""

    def __init__(self, model: "Viscoelastic", dt: float, params, limits_kv: tuple, u_start_kv: float,
                 max_step_kv: float, reference_scale: float):
        n = _physics_setup(self, model, dt, params)
        tol = 1e-12 * (1.0 + abs(float(reference_scale)) / self._length)
        self._limits = np.array([limits_kv[0], limits_kv[1], u_start_kv, max_step_kv, tol])
        self._work = np.empty((6, n))
        self._head = np.zeros(5)  # the state's head and the last sample's clipped flag
        self._x = self._state[4:]
        self.reset()

    def _rest(self) -> np.ndarray:
        return np.concatenate(([1.0, 0.0, 1.0, 0.0], dea_physics.initial_state(self._phys, self.model.n_branches)))

    def _valid(self, array: np.ndarray) -> bool:
        # the physics may hold what a failed interval left (as the batch inverse carries it on)
        return bool(np.all(np.isfinite(array[:4])) and array[2] >= 1 and array[2] == int(array[2]))

    def _advance(self, y_ref: float) -> float:
        head = self._head
        head[:4] = self._state[:4]
        u_kv = dea_physics.inverse_stepper_sample((y_ref - self._offset) / self._length, self.dt, self._phys,
                                                  self.model.n_branches, self._x, head, self._limits,
                                                  self._inv_6tau, self._work)
        self._state[:4] = head[:4]
        self.clipped = bool(head[4] != 0.0)
        self.n_clipped += self.clipped
        return u_kv / self._kv


# Default bounds in units of the data's stress scale S (kPa) and time scale T (s).
MU_BOUNDS = (1e-3, 3.0)  # x S
BRANCH_MU_BOUNDS = (1e-3, 30.0)  # x S
ETA_BOUNDS = (1e-2, 10.0)  # x S T
TAU_BOUNDS = (0.02, 500.0)  # x T
LENGTH_BOUNDS = (0.1, 10.0)  # x the hyperparameter length0


class Viscoelastic(HysteresisModel):
    """Physics-based DEA model; hyperparameters default to the virtual DEA's constants."""

    name = "viscoelastic"
    inverse_unavailable = None  # invert: dea_physics.invert_stretch
    presets_available = ("virtual-dea",)

    def __init__(
        self,
        n_branches: int = 3,
        gent_limit: float = TRUTH.J,
        prestretch: float = TRUTH.lam0,
        transverse_prestretch: float = TRUTH.lam_t,
        length_ratio: float = TRUTH.L_passive / TRUTH.L_active,
        length0: float = TRUTH.L_active * 1e3,
        thickness: float = TRUTH.H,
        eps_r: float = TRUTH.eps_r,
        volts_per_input_unit: float = 1000.0,
        offset: bool = True,
        warmup_stride: int = 5,
    ):
        name = self.name
        self.n_branches = check_int(name, "n_branches", n_branches, 0, 8)
        self.gent_limit = check_number(name, "gent_limit", gent_limit, positive=True)
        self.prestretch = check_number(name, "prestretch", prestretch, positive=True)
        self.transverse_prestretch = check_number(name, "transverse_prestretch", transverse_prestretch, positive=True)
        self.length_ratio = check_number(name, "length_ratio", length_ratio, positive=True)
        self.length0 = check_number(name, "length0", length0, positive=True)
        self.thickness = check_number(name, "thickness", thickness, positive=True)
        self.eps_r = check_number(name, "eps_r", eps_r, positive=True)
        self.volts_per_input_unit = check_number(name, "volts_per_input_unit", volts_per_input_unit, positive=True)
        self.offset = check_bool(name, "offset", offset)
        self.warmup_stride = check_int(name, "warmup_stride", warmup_stride, 1, 1000)

    # --- scales ------------------------------------------------------------
    def stress_scale_kpa(self, scale: DataScale) -> float:
        """S: the stiffness (kPa per unit stretch) that gives the data's output at its largest input."""
        phi = scale.u * self.volts_per_input_unit
        s_maxwell = self.eps_r * dea_physics.EPS0 * (phi / self.thickness) ** 2 * self.prestretch \
            * self.transverse_prestretch**2
        return 1e-3 * s_maxwell * self.length0 / scale.y

    # --- parameters ------------------------------------------------------
    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        S, T = self.stress_scale_kpa(scale), scale.time
        K = self.n_branches
        params = [
            Parameter("mu", 0.1 * S, MU_BOUNDS[0] * S, MU_BOUNDS[1] * S, False, "Gent spring modulus (kPa)", unit="kPa"),
            Parameter("eta_v", 0.1 * S * T, ETA_BOUNDS[0] * S * T, ETA_BOUNDS[1] * S * T, False,
                      "parallel dashpot viscosity (kPa s)", unit="kPa*s"),
        ]
        for k in range(K):
            params.append(Parameter(f"mu{k + 1}", S, BRANCH_MU_BOUNDS[0] * S, BRANCH_MU_BOUNDS[1] * S, False,
                                    f"modulus of Maxwell branch {k + 1} (kPa)", unit="kPa"))
        for k in range(K):
            tau = min(T * 0.3 * 10.0**k, 0.5 * TAU_BOUNDS[1] * T)
            params.append(Parameter(f"tau{k + 1}", tau, TAU_BOUNDS[0] * T, TAU_BOUNDS[1] * T, False,
                                    f"relaxation time of Maxwell branch {k + 1} (s)", unit="s"))
        params.append(Parameter("length", self.length0, LENGTH_BOUNDS[0] * self.length0,
                                LENGTH_BOUNDS[1] * self.length0, True,
                                "unstretched length of the active region (output units per unit stretch)", unit="y"))
        if self.offset:
            params.append(self.offset_parameter(scale))
        return params

    def preset(self, name: str) -> dict[str, float]:
        if name != "virtual-dea":
            return super().preset(name)
        if (self.n_branches, self.gent_limit, self.prestretch, self.transverse_prestretch, self.length_ratio,
                self.thickness, self.eps_r, self.volts_per_input_unit) != (
                TRUTH.n_branches, TRUTH.J, TRUTH.lam0, TRUTH.lam_t, TRUTH.L_passive / TRUTH.L_active, TRUTH.H,
                TRUTH.eps_r, 1000.0):
            raise ModelError(f"preset 'virtual-dea' needs the default hyperparameters; this model is {self!r}")
        p = {"mu": TRUTH.mu * 1e-3, "eta_v": TRUTH.eta_v * 1e-3}
        p.update({f"mu{k + 1}": m * 1e-3 for k, m in enumerate(TRUTH.mu_k)})
        p.update({f"tau{k + 1}": t for k, t in enumerate(TRUTH.tau_k)})
        p["length"] = TRUTH.L_active * 1e3
        if self.offset:
            p["offset"] = 0.0
        return p

    # --- physics -------------------------------------------------------------
    def physical_vectors(self, nonlinear_sets: np.ndarray) -> np.ndarray:
        """Rows of nonlinear parameters (``nonlinear_names`` order; full parameter rows are
        accepted too, their linear columns are ignored) -> ``dea_physics`` parameter vectors (SI)."""
        N = np.ascontiguousarray(np.atleast_2d(np.asarray(nonlinear_sets, dtype=float)))
        K = self.n_branches
        if N.ndim != 2 or N.shape[1] not in (2 + 2 * K, self.n_params):
            raise ModelError(f"model {self.name!r} takes {self.n_params} parameters ({', '.join(self.param_names)}), "
                             f"got an array of shape {np.shape(nonlinear_sets)}")
        phys = np.empty((N.shape[0], dea_physics.N_FIXED + 2 * K))
        L = 1e-3 * self.length0  # any length: the output scales with ``length``, only the ratio matters here
        phys[:, 0] = N[:, 0] * 1e3
        phys[:, 1] = self.gent_limit
        phys[:, 2] = N[:, 1] * 1e3
        phys[:, 3] = self.prestretch
        phys[:, 4] = self.transverse_prestretch
        phys[:, 5] = L
        phys[:, 6] = L * self.length_ratio
        phys[:, 7] = self.thickness
        phys[:, 8] = self.eps_r
        phys[:, 9:9 + K] = N[:, 2:2 + K] * 1e3
        phys[:, 9 + K:9 + 2 * K] = N[:, 2 + K:2 + 2 * K]
        return phys

    def stretch_batch(self, u, dt: float, nonlinear_sets, window=None) -> np.ndarray:
        """lam_a - lam0 for each parameter set, shape (n_sets, samples of ``window``); the
        actuator is always simulated from the first sample, only the window is stored, and the
        samples before the window are crossed with RK4 steps of up to ``warmup_stride`` samples."""
        u = self._check_input(u, dt)
        phys = self.physical_vectors(nonlinear_sets)
        w = self._window(u, slice(None) if window is None else window)
        start, stop, rows = w.start, w.stop, w.rows  # a row subset: its span is simulated, the rows kept
        u_kv = u * (self.volts_per_input_unit / 1000.0)
        stride = self.warmup_stride if window is not None else 1
        out = dea_physics.simulate_window_batch(u_kv, float(dt), phys, self.n_branches, start, stop, stride)
        return out if rows is None else np.ascontiguousarray(out[:, rows - start])

    # --- inverse --------------------------------------------------------
    def invert(self, y_desired, dt: float, params, input_range=None, input_limits=None,
               max_rate: float | None = None, u_start: float | None = None) -> Inversion:
        """The causal inverse (``dea_physics.invert_stretch``): the input within ``input_limits``
        (input units; default ``input_range``) whose output is ``y_desired``, sample by sample;
        ``max_rate`` limits |du/dt| (input units per s), ``u_start`` is the input at sample 0
        (default the lower limit). The output at sample 0 is the rest output whatever the input."""
        a = InverseArguments.check(self.name, y_desired, dt, input_range, input_limits, 2, max_rate, u_start)
        yd = a.yd
        P = self._check_param_sets(self.pack(params) if isinstance(params, Mapping) else params)
        K = self.n_branches
        length = P[0, 2 + 2 * K]
        offset = P[0, 3 + 2 * K] if self.offset else 0.0
        if not length > 0:
            raise ModelError(f"{self.name}: invert needs a positive length, got {length!r}")
        kv = self.volts_per_input_unit / 1000.0
        lo, hi, start = a.lo * kv, a.hi * kv, a.u_start * kv
        step = a.max_step * kv
        dlam = (yd - offset) / length
        tol = 1e-12 * (1.0 + float(np.max(np.abs(dlam))))
        u_kv, clipped = dea_physics.invert_stretch(dlam, float(dt), self.physical_vectors(P)[0], K, lo, hi, start, step,
                                                   tol)
        return Inversion(u_kv / kv, clipped)

    def stepper(self, dt: float, params, input_range=None) -> ViscoelasticStepper:
        """A constant-time ``ViscoelasticStepper`` (the batch kernel's RK4 sample interval per step)."""
        self._check_causal()
        return ViscoelasticStepper(self, dt, params)

    def inverse_stepper(self, dt: float, params, input_range=None, input_limits=None,
                        max_rate: float | None = None, u_start: float | None = None,
                        reference_scale: float | None = None) -> ViscoelasticInverseStepper:
        """The inverse one sample at a time in constant time (``ViscoelasticInverseStepper``), equal to
        ``invert`` with the same options; ``reference_scale``: the largest |y_ref - offset| of the
        references (sets the reach tolerance as ``invert`` sets it from its whole reference)."""
        self.invert(np.zeros(1), dt, params, input_range, input_limits, max_rate=max_rate,
                    u_start=u_start)  # refuse bad options now, in invert's words
        a = InverseArguments.check(self.name, np.zeros(1), dt, input_range, input_limits, 2, max_rate, u_start)
        kv = self.volts_per_input_unit / 1000.0
        lo, hi, start = a.lo * kv, a.hi * kv, a.u_start * kv
        step = a.max_step * kv
        scale = 0.0 if reference_scale is None else check_number(self.name, "reference_scale", reference_scale)
        return ViscoelasticInverseStepper(self, dt, params, (lo, hi), start, step, scale)

    # --- evaluation ------------------------------------------------------
    def _linear_part(self, P: np.ndarray, dlam: np.ndarray) -> np.ndarray:
        K = self.n_branches
        y = P[:, 2 + 2 * K, None] * dlam
        if self.offset:
            y += P[:, 3 + 2 * K, None]
        return y

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        P = self._check_param_sets(param_sets)
        return self._linear_part(P, self.stretch_batch(u, dt, P))

    def simulate_window_batch(self, u, dt: float, param_sets, window, input_range=None) -> np.ndarray:
        P = self._check_param_sets(param_sets)
        return self._linear_part(P, self.stretch_batch(u, dt, P, window))

    def _check_nonlinear(self, nonlinear: Mapping[str, float]) -> np.ndarray:
        expected = set(self.nonlinear_names)
        if set(nonlinear) != expected:
            raise ModelError(f"{self.name}: regressors need exactly the nonlinear parameters {sorted(expected)}, "
                             f"got {sorted(nonlinear)}")
        return np.array([float(nonlinear[n]) for n in self.nonlinear_names])

    def _regressor_columns(self, dlam: np.ndarray) -> np.ndarray:
        """(n_sets, rows) stretches -> (n_sets, rows, n_linear) in ``linear_names`` order."""
        cols = [dlam] + ([np.ones_like(dlam)] if self.offset else [])
        return np.stack(cols, axis=-1)

    def regressors(self, u, dt: float, nonlinear: Mapping[str, float], input_range=None) -> np.ndarray:
        row = self._check_nonlinear(dict(nonlinear))
        return self._regressor_columns(self.stretch_batch(u, dt, row[None, :]))[0]

    def windowed_regressors(self, u, dt: float, nonlinear: Mapping[str, float], window,
                            input_range=None) -> np.ndarray:
        row = self._check_nonlinear(dict(nonlinear))
        return self._regressor_columns(self.stretch_batch(u, dt, row[None, :], window))[0]

    def windowed_regressors_batch(self, u, dt: float, nonlinear_sets: np.ndarray, window,
                                  input_range=None) -> np.ndarray:
        N = np.asarray(nonlinear_sets, dtype=float)
        N = N.reshape(1, -1) if N.ndim < 2 else N
        if N.shape[1] != len(self.nonlinear_names):
            raise ModelError(f"{self.name}: nonlinear parameter sets need {len(self.nonlinear_names)} columns "
                             f"({', '.join(self.nonlinear_names)}), got shape {N.shape}")
        return self._regressor_columns(self.stretch_batch(u, dt, N, window))
