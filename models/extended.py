"""A hysteresis model extended by the components a diagnosis can name.

``ExtendedModel(base="mrpim", components=("relaxation",))`` is registered as
``mrpim+relaxation`` (and likewise for every cause; see ``CAUSES``). The
output is built in the order of a physical measurement chain:

    actuator   y_a(t') = B[v](t') + sum_k sum_p c_kp L_tau_k[v^p](t') + s (1 - exp(-t' / T_c))
    mechanics  y_m     = H[y_a - c] + c                      (resonance; c = the base's ``offset``)
    timing     v(t') = u(t' - d) ... the actuator receives the input d late: it starts at t = d
               (own time t' = t - d) and shows its rest output before (delay)
    sensor     y(t)  = clip(y_m(t - d) + a sin(2 pi f_i t) + b cos(2 pi f_i t), level)

* ``relaxation``: first-order low-pass histories L_tau of the input's powers
  (``relaxation_powers``, default u only) with ``n_relaxation`` time constants
  tau_k (nonlinear) and weights c_kp (linear). A Maxwell-type branch: the
  output depends on how the input was a time tau ago.
* ``creep``: a slow drift since the record's start, size s (linear, output
  units) and time scale T_c (nonlinear, s).
* ``resonance``: H is the second-order low-pass of unit static gain,
  natural frequency f_n (Hz) and damping ratio zeta (both nonlinear). The
  base's output offset (a sensor zero) is not filtered. The mode starts at
  rest at the actuator's first output (in equilibrium with it).
* ``delay``: a pure delay d (s, nonlinear): the whole actuator (base and the
  components above) runs on the input sampled at t - d (linear between
  samples), from rest at t = d; before that the output is the base's rest
  output for the record's first input held (the input before the record
  starts is taken to be its first value).
* ``interference``: a sinusoid at f_i (Hz, nonlinear) with linear sine and
  cosine weights, in the record's own time (t = 0 at its first sample); a
  disturbance with the same phase relative to every record's start.
* ``saturation``: the output clipped at ``level`` (nonlinear, output units)
  from above (``saturation_side="upper"``) or below ("lower"). Clipping makes
  no parameter enter linearly, so this model has no regressors (identify it
  with ``lsq`` or ``mpso``).

Stepping (``stepper``): the P-I stepper where the model has a step structure; else the chain of
per-sample blocks of ``extended_stepper`` (a ring buffer for the delay, the batch filter's step for
the mode, the clip), constant time per sample and equal to ``simulate``.

Every dynamic block but the mode starts from rest (the signal it receives is zero before
t = 0; see ``filter_kernels``); the rest output of a late actuator is the
base's output for the record's first input sample. Without saturation the model stays linear in the base's
linear parameters and in the components' weights, so ``regressors`` applies
the same blocks to each column of the base's regressor matrix and varpro
identifies it directly.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Mapping, MutableMapping, Sequence

import numpy as np
from numba.typed import List as TypedList

from .base import DataScale, HysteresisModel, Parameter
from .errors import ModelError
from .hyperparameters import check_choice, check_int, check_int_list
from .inverse import StepInvertible, StepStructure
from . import extended_stepper
from .pi_stepper import SteppableStructure
from .filter_kernels import (
    first_order_foh,
    lowpass1_bank,
    lowpass1_bank_at,
    lowpass2_columns_at,
    lowpass2_rows,
    lowpass2_sets,
    second_order_foh,
)
from .registry import get_model, is_registered, register
from .window import Window

CAUSES = ("relaxation", "delay", "resonance", "creep", "interference", "saturation")
ORDER = {c: i for i, c in enumerate(CAUSES)}

# Default bounds, in units of the data scale (DataScale: u, y, time = shortest drive period).
TAU_BOUNDS = (0.01, 1000.0)  # x time
RELAX_WEIGHT_BOUND = 20.0  # |c_kp| <= bound * y / u^p
DELAY_BOUND = 0.25  # 0 <= d <= bound * time
RESONANCE_HZ_BOUNDS = (1.0, 500.0)  # x 1 / time
DAMPING_BOUNDS = (0.01, 3.0)
CREEP_TIME_BOUNDS = (1.0, 10000.0)  # x time
CREEP_SIZE_BOUND = 2.0  # x y
INTERFERENCE_HZ_BOUNDS = (0.5, 500.0)  # x 1 / time
INTERFERENCE_BOUND = 1.0  # x y
SATURATION_BOUND = 2.0  # |level| <= bound * y
KEPT = 8  # entries kept in a cache of ``windowed_regressors`` (each at most a delayed input: 3.4 MB at 420,000 samples)


def extended_name(base: str, components: Sequence[str]) -> str:
    return "+".join([base, *components])


class ExtendedModel(SteppableStructure, HysteresisModel):
    """A registered base model plus named components; see the module docstring."""

    name = "extended"

    def __init__(self, base: str = "mrpim", components: Sequence[str] = ("relaxation",),
                 base_hyperparameters: Mapping | None = None, n_relaxation: int = 1,
                 relaxation_powers: Sequence[int] = (1,), saturation_side: str = "upper"):
        owner = "extended model"
        if not isinstance(base, str):
            raise ModelError(f"{owner}: base must be a registered model name, got {base!r}")
        if isinstance(components, str) or not isinstance(components, (list, tuple, set, frozenset)) or not all(
                isinstance(c, str) for c in components):
            raise ModelError(f"{owner}: components must be a list of names from {', '.join(CAUSES)}, "
                             f"got {components!r}")
        if base_hyperparameters is not None and not isinstance(base_hyperparameters, Mapping):
            raise ModelError(f"{owner}: base_hyperparameters must be a mapping name -> value, "
                             f"got {base_hyperparameters!r}")
        self.base = base
        self.components = tuple(sorted(set(components), key=lambda c: ORDER.get(c, len(ORDER))))
        self.base_hyperparameters = dict(base_hyperparameters or {})
        self.n_relaxation = check_int(owner, "n_relaxation", n_relaxation, 1, 6)
        self.relaxation_powers = check_int_list(owner, "relaxation_powers", relaxation_powers, 1, 4)
        if len(set(self.relaxation_powers)) != len(self.relaxation_powers):
            raise ModelError(f"{owner}: relaxation_powers must not repeat a power, got {relaxation_powers!r}")
        self.saturation_side = check_choice(owner, "saturation_side", saturation_side, ("upper", "lower"))
        unknown = [c for c in components if c not in CAUSES]
        if unknown or not self.components:
            raise ModelError(f"extended model: unknown or no components {list(components)!r}; "
                             f"choose from {', '.join(CAUSES)}")
        self.base_model = get_model(base, **self.base_hyperparameters)
        if isinstance(self.base_model, ExtendedModel):
            raise ModelError("extended model: the base must not itself be extended (list all components instead)")
        self.name = extended_name(base, self.components)

    def get_hyperparameters(self) -> dict:
        return {"base": self.base, "components": list(self.components),
                "base_hyperparameters": dict(self.base_hyperparameters), "n_relaxation": self.n_relaxation,
                "relaxation_powers": list(self.relaxation_powers), "saturation_side": self.saturation_side}

    def has(self, component: str) -> bool:
        return component in self.components

    # --- parameters ------------------------------------------------------
    def component_parameters(self, scale: DataScale | None = None) -> tuple[Parameter, ...]:
        """The components' own parameters (the base's come first in ``parameters``)."""
        s = scale or DataScale()
        T, y, u = s.time, s.y, s.u
        linear = not self.has("saturation")
        out = []
        if self.has("relaxation"):
            lo, hi = TAU_BOUNDS[0] * T, TAU_BOUNDS[1] * T
            for k in range(1, self.n_relaxation + 1):
                start = min(hi, max(lo, T * 10.0 ** (k - 1)))
                out.append(Parameter(f"tau{k}", start, lo, hi, False, f"relaxation time {k} (s)", log_scale=True,
                                     unit="s"))
            for k in range(1, self.n_relaxation + 1):
                for p in self.relaxation_powers:
                    b = RELAX_WEIGHT_BOUND * y / u**p
                    out.append(Parameter(f"c{k}" + ("" if p == 1 else f"_u{p}"), 0.0, -b, b, linear,
                                         f"weight of the low-pass history of u^{p} with tau{k}", unit=f"y/u^{p}"))
        if self.has("delay"):
            out.append(Parameter("delay", 0.0, 0.0, DELAY_BOUND * T, False, "pure time delay (s)", unit="s"))
        if self.has("resonance"):
            lo, hi = RESONANCE_HZ_BOUNDS[0] / T, RESONANCE_HZ_BOUNDS[1] / T
            out.append(Parameter("natural_frequency", min(hi, 20.0 / T), lo, hi, False,
                                 "natural frequency of the mode (Hz)", log_scale=True, unit="Hz"))
            out.append(Parameter("damping_ratio", 0.5, *DAMPING_BOUNDS, False, "damping ratio of the mode",
                                 log_scale=True, unit="1"))
        if self.has("creep"):
            out.append(Parameter("creep_time", 100.0 * T, CREEP_TIME_BOUNDS[0] * T, CREEP_TIME_BOUNDS[1] * T,
                                 False, "creep time scale (s)", log_scale=True, unit="s"))
            out.append(Parameter("creep_size", 0.0, -CREEP_SIZE_BOUND * y, CREEP_SIZE_BOUND * y, linear,
                                 "creep size (output units): s in s (1 - exp(-t / T_c))", unit="y"))
        if self.has("interference"):
            lo, hi = INTERFERENCE_HZ_BOUNDS[0] / T, INTERFERENCE_HZ_BOUNDS[1] / T
            out.append(Parameter("interference_frequency", min(hi, 10.0 / T), lo, hi, False,
                                 "frequency of the disturbance (Hz)", unit="Hz"))
            b = INTERFERENCE_BOUND * y
            out.append(Parameter("interference_sin", 0.0, -b, b, linear, "sine weight of the disturbance", unit="y"))
            out.append(Parameter("interference_cos", 0.0, -b, b, linear, "cosine weight of the disturbance", unit="y"))
        if self.has("saturation"):
            b = SATURATION_BOUND * y
            out.append(Parameter("saturation_level", y if self.saturation_side == "upper" else -y, -b, b, False,
                                 f"level the output is clipped at from {'above' if self.saturation_side == 'upper' else 'below'}",
                                 unit="y"))
        return tuple(out)

    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        base = self.base_model.parameters(scale)
        if self.has("saturation"):  # clipping: nothing enters the output linearly
            base = tuple(replace(p, linear=False) for p in base)
        params = base + self.component_parameters(scale)
        names = [p.name for p in params]
        if len(set(names)) != len(names):
            raise ModelError(f"{self.name}: base parameter names clash with the components' ({names})")
        return list(params)

    @property
    def base_names(self) -> tuple[str, ...]:
        return self.base_model.param_names

    # --- pieces --------------------------------------------------------------
    def _relaxation_columns(self, u: np.ndarray, dt: float, taus: Sequence[float],
                            at: np.ndarray | None = None, cache: MutableMapping | None = None) -> np.ndarray:
        """(n_relaxation * n_powers, T): L_tau_k[u^p], k-major, in the weights' order; with ``at`` (sorted,
        distinct sample indices) only those samples are kept: (..., at.size). ``cache``: the caller's
        {(tau, p): row} for this u, dt and ``at``, read and filled (each tau's filter runs alone, so a row
        does not depend on which other rows were computed with it)."""
        if cache is not None and at is not None:
            powers = tuple(self.relaxation_powers)
            missing = list(dict.fromkeys(float(t) for t in taus if any((float(t), p) not in cache for p in powers)))
            if missing:
                fresh = self._relaxation_columns(u, dt, missing, at)
                for i, t in enumerate(missing):
                    for j, p in enumerate(powers):
                        cache[(t, p)] = fresh[i * len(powers) + j]
            return np.stack([cache[(float(t), p)] for t in taus for p in powers])
        a, b0, b1 = (np.array(c) for c in zip(*(first_order_foh(float(t), dt) for t in taus)))
        if at is None:
            bank = lowpass1_bank
        else:
            at = np.ascontiguousarray(at, dtype=np.int64)
            bank = lambda v, a, b0, b1: lowpass1_bank_at(v, a, b0, b1, at)  # noqa: E731
        if tuple(self.relaxation_powers) == (1,):  # the bank's rows are already in the weights' order
            return bank(np.ascontiguousarray(u, dtype=float), a, b0, b1)
        rows = []
        for p in self.relaxation_powers:
            rows.append(bank(np.ascontiguousarray(u**p), a, b0, b1))  # (K, T)
        n_p = len(self.relaxation_powers)
        out = np.empty((len(taus) * n_p, rows[0].shape[1]))
        for k in range(len(taus)):
            for j in range(n_p):
                out[k * n_p + j] = rows[j][k]
        return out

    def _relaxation_weight_names(self) -> list[str]:
        """c{k}[_u{p}], k-major: the order of ``_relaxation_columns``."""
        return [f"c{k}" + ("" if p == 1 else f"_u{p}") for k in range(1, self.n_relaxation + 1)
                for p in self.relaxation_powers]

    @staticmethod
    def _creep_column(n: int | np.ndarray, dt: float, creep_time: float, t0: float = 0.0) -> np.ndarray:
        """The creep column over n samples, or at the sample indices ``n`` (an array)."""
        k = np.arange(n) if np.ndim(n) == 0 else n
        return -np.expm1(-(t0 + k * dt) / creep_time)

    @staticmethod
    def interference_columns(n: int | np.ndarray, dt: float, f: float) -> np.ndarray:
        """The (sin, cos) columns over n samples, or at the sample indices ``n`` (an array)."""
        phase = 2.0 * np.pi * f * dt * (np.arange(n) if np.ndim(n) == 0 else n)
        return np.stack([np.sin(phase), np.cos(phase)])

    def _check_range(self, params: Mapping[str, float]) -> None:
        for name in ("tau1", "creep_time", "natural_frequency", "interference_frequency"):
            if name in params and not params[name] > 0:
                raise ModelError(f"{self.name}: {name} must be positive, got {params[name]!r}")
        for k in range(2, self.n_relaxation + 1):
            if self.has("relaxation") and not params[f"tau{k}"] > 0:
                raise ModelError(f"{self.name}: tau{k} must be positive, got {params[f'tau{k}']!r}")
        if self.has("delay") and not params["delay"] >= 0:
            raise ModelError(f"{self.name}: delay must not be negative, got {params['delay']!r}")
        if self.has("resonance") and not params["damping_ratio"] > 0:
            raise ModelError(f"{self.name}: damping_ratio must be positive, got {params['damping_ratio']!r}")

    # --- the step structure (the causal inverse, models/inverse.py) -----
    @property
    def time_varying_base(self) -> bool:
        return self.has("creep") or self.has("interference")

    @property
    def inverse_unavailable(self) -> str | None:
        if not isinstance(self.base_model, StepInvertible):
            return f"its base {self.base!r} has no step structure"
        reason = self.base_model.inverse_unavailable
        if reason:
            return reason
        why = {"delay": "the delay makes the output at a sample independent of the input at it (the inverse "
                        "would need the reference ahead of time)",
               "resonance": "the mode's low-pass makes the output at a sample almost independent of the input "
                            "at it (relative degree 2): no sample-by-sample inverse",
               "saturation": "no step structure for the clipped output is implemented"}
        for component in self.components:
            if component in why:
                return why[component]
        return None

    def step_structure(self, dt: float, params, input_range, n_samples: int) -> StepStructure:
        """The base's step arrays plus relaxation filters and the known-in-time creep and interference."""
        s = self.base_model.step_structure(dt, {k: params[k] for k in self.base_names}, input_range, n_samples)
        base = np.array(s.base, dtype=float)
        if self.has("relaxation"):
            coef = [first_order_foh(float(params[f"tau{k}"]), dt) for k in range(1, self.n_relaxation + 1)]
            n_p = len(self.relaxation_powers)
            s.filter_a = np.array([c[0] for c in coef for _ in range(n_p)])
            s.filter_b0 = np.array([c[1] for c in coef for _ in range(n_p)])
            s.filter_b1 = np.array([c[2] for c in coef for _ in range(n_p)])
            s.filter_power = np.array(list(self.relaxation_powers) * len(coef), dtype=np.int64)
            s.filter_weight = np.array([params[w] for w in self._relaxation_weight_names()])
        s.base = self.varying_base(base, np.arange(n_samples), dt, params)
        return s

    def varying_base(self, base: np.ndarray, k: np.ndarray, dt: float, params) -> np.ndarray:
        """The step structure's offset at the sample indices ``k``: the base's offset ``base`` (one per
        index) plus the creep and interference there. ``step_structure`` computes it for 0..n-1; a
        stepper for a block of samples anywhere in time, with the same arithmetic (so the same bits)."""
        base = np.array(base, dtype=float)
        if self.has("creep"):
            base += params["creep_size"] * self._creep_column(k, dt, params["creep_time"])
        if self.has("interference"):
            cols = self.interference_columns(k, dt, params["interference_frequency"])
            base += params["interference_sin"] * cols[0] + params["interference_cos"] * cols[1]
        return base

    # --- causal stepper (models/extended_stepper.py) --------------------
    def stepper(self, dt: float, params, input_range=None):
        """A constant-time stepper: the P-I stepper where the model has a step structure, else the
        measurement chain's per-sample blocks around the actuator's stepper (``extended_stepper``)."""
        self._check_causal()
        if not self.inverse_unavailable:
            return super().stepper(dt, params, input_range)
        vec = self.pack(params) if isinstance(params, Mapping) else np.asarray(params, dtype=float)
        values = self.unpack(vec)
        self._check_range(values)
        return extended_stepper.build(self, self.components, float(dt), values, input_range)

    @property
    def noncausal_reason(self) -> str | None:
        """The base's: the components are causal."""
        return self.base_model.noncausal_reason

    # --- evaluation ------------------------------------------------------
    @staticmethod
    def delayed_input(u: np.ndarray, dt: float, delay: float) -> tuple[np.ndarray, int, float]:
        """The input as a late actuator receives it: (u_a, k0, t0). The actuator starts at record
        sample k0 = ceil(d / dt); its sample j is record sample k0 + j, at its own time
        t0 + j dt = (k0 + j) dt - d, where it receives u((k0 + j) dt - d) (linear between samples)."""
        k0, frac0 = extended_stepper.delay_samples(delay, dt)
        n = u.size
        if k0 <= 0:
            return u, 0, 0.0
        if k0 >= n:
            return u[:0], n, 0.0
        pos = np.arange(n - k0) + frac0
        return np.interp(pos, np.arange(n), u), k0, frac0 * dt

    def _actuator_batch(self, u: np.ndarray, dt: float, t0: float, P: np.ndarray, input_range) -> np.ndarray:
        """Base + relaxation + creep, through the resonance: (n_sets, len(u)), for an actuator that
        receives u from its own time t0 on."""
        names = self.param_names
        nb = len(self.base_names)
        n = u.size
        Y = np.array(self.base_model.simulate_batch(u, dt, np.ascontiguousarray(P[:, :nb]), input_range=input_range),
                     dtype=float, copy=True)
        sets = [dict(zip(names, row)) for row in P]
        if self.has("relaxation"):
            weights = self._relaxation_weight_names()
            for i, s in enumerate(sets):
                cols = self._relaxation_columns(u, dt, [s[f"tau{k}"] for k in range(1, self.n_relaxation + 1)])
                Y[i] += np.array([s[w] for w in weights]) @ cols
        if self.has("creep"):
            for i, s in enumerate(sets):
                Y[i] += s["creep_size"] * self._creep_column(n, dt, s["creep_time"], t0)
        if self.has("resonance"):
            off = np.array([s.get("offset", 0.0) for s in sets])[:, None] if "offset" in self.base_names else 0.0
            coef = [second_order_foh(s["natural_frequency"], s["damping_ratio"], dt) for s in sets]
            phis = np.ascontiguousarray(np.stack([c[0] for c in coef]))
            g0 = np.ascontiguousarray(np.stack([c[1] for c in coef]))
            g1 = np.ascontiguousarray(np.stack([c[2] for c in coef]))
            Y = lowpass2_sets(np.ascontiguousarray(Y - off), phis, g0, g1) + off
        return Y

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        names = self.param_names
        n_set, n = P.shape[0], u.size
        sets = [dict(zip(names, row)) for row in P]
        for s in sets:
            self._check_range(s)
        in_range = self._input_range(u, input_range)  # the record's structure, also for a late actuator
        if not self.has("delay"):
            Y = self._actuator_batch(u, dt, 0.0, P, in_range)
        else:
            nb = len(self.base_names)
            rest = self.base_model.simulate_batch(u[:1], dt, np.ascontiguousarray(P[:, :nb]),
                                                  input_range=in_range)[:, 0]
            Y = np.empty((n_set, n))
            for i, s in enumerate(sets):
                u_a, k0, t0 = self.delayed_input(u, dt, s["delay"])
                Y[i, :k0] = rest[i]
                if k0 < n:
                    Y[i, k0:] = self._actuator_batch(u_a, dt, t0, P[i:i + 1], in_range)[0]
        if self.has("interference"):
            for i, s in enumerate(sets):
                cols = self.interference_columns(n, dt, s["interference_frequency"])
                Y[i] += s["interference_sin"] * cols[0] + s["interference_cos"] * cols[1]
        if self.has("saturation"):
            levels = np.array([s["saturation_level"] for s in sets])[:, None]
            Y = np.minimum(Y, levels) if self.saturation_side == "upper" else np.maximum(Y, levels)
        return Y

    def _nonlinear(self, nonlinear) -> dict:
        if self.has("saturation"):
            raise ModelError(f"model {self.name!r} has no linear part to solve exactly (clipping); use lsq or mpso")
        nonlinear = dict(nonlinear or {})
        expected = set(self.nonlinear_names)
        if set(nonlinear) != expected:
            raise ModelError(f"{self.name}: regressors need exactly the nonlinear parameters {sorted(expected)}, "
                             f"got {sorted(nonlinear)}")
        self._check_range(nonlinear)
        return nonlinear

    def _actuator_input(self, u: np.ndarray, dt: float, delay: float, w: Window) -> dict:
        """The input as the actuator receives it (``u_a``, its own time ``t0`` at its first sample), the
        window's rows before it starts (``n_rest``), its rows in the actuator's samples (``at``, among its first
        ``a1``; ``pick`` for the base) and a dict for its filtered inputs (``relaxation``)."""
        u_a, k0, t0 = self.delayed_input(u, dt, delay) if self.has("delay") else (u, 0, 0.0)
        n_rest = min(max(k0 - w.start, 0), len(w)) if w.rows is None else int(np.searchsorted(w.rows, k0))
        a = {"u_a": u_a, "t0": t0, "n_rest": n_rest, "a1": w.stop - k0, "relaxation": {}}
        if a["a1"] > 0 and n_rest < len(w):
            if w.rows is None:
                a["pick"] = slice(max(w.start, k0) - k0, a["a1"])
                a["at"] = np.arange(a["a1"])[a["pick"]]
            else:  # the rows shifted: still increasing, no need to check them again
                a["at"] = w.rows[n_rest:] - k0
                a["pick"] = Window(int(a["at"][0]), a["a1"], a["at"])
        return a

    def _window_columns(self, u: np.ndarray, dt: float, nonlinear: Mapping[str, float], window, in_range,
                        out: np.ndarray, cache: MutableMapping | None = None) -> None:
        """Fill out (n_linear, n_rows) with the regressor rows of ``window`` (a slice or increasing
        sample indices), the model run from sample 0. ``cache``: a dict the caller keeps for these u, dt,
        window and input range, where what depends on the delay alone (``_actuator_input``), on the base's
        parameters alone (its rest row) or on both (its columns at the rows) is kept: a fit that moves a
        component's own parameter recomputes only that component's columns."""
        base_nl = {k: nonlinear[k] for k in self.base_model.nonlinear_names}
        base_key = tuple(float(v) for v in base_nl.values())
        w = self._window(u, window)
        delay = float(nonlinear["delay"]) if self.has("delay") else 0.0
        a = _kept(cache, ("input", delay), lambda: self._actuator_input(u, dt, delay, w))
        names = self.linear_names
        n_rest, a1 = a["n_rest"], a["a1"]
        if n_rest:  # leading rows before the actuator starts
            rest = _kept(cache, ("rest", *base_key), lambda: self.base_rest(dt, base_nl, in_range, u[:1]))
            for j, name in enumerate(names):
                out[j, :n_rest] = rest.get(name, 0.0)
        if "at" in a:
            u_a = a["u_a"][:a1]
            if self.has("resonance"):  # the filter needs every sample up to the window's end (too large to keep)
                cols = self.assemble_columns(u_a, dt, self.base_columns(u_a, dt, base_nl, in_range), nonlinear,
                                             a["t0"], rows=a["at"])
            else:
                def base():
                    B = self.base_model.windowed_regressors(a["u_a"], dt, base_nl, a["pick"], input_range=in_range)
                    return {name: B[:, j] for j, name in enumerate(self.base_model.linear_names)}
                cols = dict(_kept(cache, ("columns", delay, *base_key), base))
                cols.update(self.assemble_columns(u_a, dt, {}, nonlinear, a["t0"], rows=a["at"],
                                                  relaxation_cache=None if cache is None else a["relaxation"]))
            for j, name in enumerate(names):
                if name in cols:
                    out[j, n_rest:] = cols[name]
        if self.has("interference"):
            samples = np.arange(w.start, w.stop) if w.rows is None else w.rows
            phase = 2.0 * np.pi * nonlinear["interference_frequency"] * dt * samples
            out[names.index("interference_sin")] = np.sin(phase)
            out[names.index("interference_cos")] = np.cos(phase)

    def regressors(self, u, dt: float, nonlinear: Mapping[str, float] | None = None, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        return self.windowed_regressors(u, dt, nonlinear, slice(0, u.size), input_range=input_range)

    def windowed_regressors(self, u, dt: float, nonlinear: Mapping[str, float] | None, window,
                            input_range=None, cache: MutableMapping | None = None) -> np.ndarray:
        nonlinear = self._nonlinear(nonlinear)
        sets = np.array([[float(nonlinear[n]) for n in self.nonlinear_names]])
        return self.windowed_regressors_batch(u, dt, sets, window, input_range, cache)[0]

    def windowed_regressors_batch(self, u, dt: float, nonlinear_sets, window, input_range=None,
                                  cache: MutableMapping | None = None) -> np.ndarray:
        """(n_sets, n_rows, n_linear); each set's matrix is column-major (a transposed view). ``cache``: see
        ``_window_columns``."""
        u = self._check_input(u, dt)
        sets = np.asarray(nonlinear_sets, dtype=float)
        sets = sets.reshape(1, -1) if sets.ndim < 2 else sets
        names = self.nonlinear_names
        if sets.shape[1] != len(names):
            raise ModelError(f"{self.name}: regressors need the nonlinear parameters {list(names)}, "
                             f"got sets of shape {sets.shape}")
        start, stop = self._window_bounds(u, window)
        rows = self._window_rows(u, window)
        in_range = self._input_range(u, input_range)
        out = np.empty((sets.shape[0], len(self.linear_names), stop - start if rows is None else rows.size))
        for i, row in enumerate(sets):
            nonlinear = self._nonlinear(dict(zip(names, (float(v) for v in row))))
            self._window_columns(u, dt, nonlinear, window, in_range, out[i], cache)
        return out.transpose(0, 2, 1)

    def base_columns(self, u: np.ndarray, dt: float, base_nonlinear: Mapping[str, float], input_range) -> dict:
        """The base's regressor columns over the whole input, by linear parameter name."""
        B = self.base_model.windowed_regressors(u, dt, dict(base_nonlinear), slice(0, u.size), input_range=input_range)
        return {name: np.ascontiguousarray(B[:, j]) for j, name in enumerate(self.base_model.linear_names)}

    def base_rest(self, dt: float, base_nonlinear: Mapping[str, float], input_range, u0: np.ndarray) -> dict[str, float]:
        """The base's regressor row for the first input sample ``u0`` held (a late actuator before it starts),
        by linear parameter name."""
        row = np.asarray(self.base_model.regressors(u0[:1], dt, dict(base_nonlinear), input_range=input_range))[0]
        return {name: float(row[j]) for j, name in enumerate(self.base_model.linear_names)}

    def assemble_columns(self, u: np.ndarray, dt: float, base_columns: Mapping[str, np.ndarray],
                         nonlinear: Mapping[str, float], t0: float = 0.0,
                         rows: np.ndarray | None = None,
                         relaxation_cache: MutableMapping | None = None) -> dict[str, np.ndarray]:
        """The actuator's regressor columns (by linear parameter name) from the base's columns:
        relaxation and creep columns added, all but the offset through the resonance. No delay or
        interference here (see ``regressors``). ``base_columns`` may hold only some of the base's
        columns (or none); ``t0`` is the actuator's own time at u's first sample. With ``rows``
        (sample indices) every column is returned at those samples only; ``relaxation_cache``: a dict the
        caller keeps for these u, dt and rows, which saves refiltering a time constant seen before."""
        n = u.size
        cols: dict[str, np.ndarray] = dict(base_columns)
        at_rows = rows is not None and not self.has("resonance")  # the mode's filter needs whole columns
        if at_rows:
            cols = {k: v[rows] for k, v in cols.items()}
        if self.has("relaxation"):
            taus = [nonlinear[f"tau{k}"] for k in range(1, self.n_relaxation + 1)]
            kept = at_rows and _increasing(rows)
            R = self._relaxation_columns(u, dt, taus, at=rows if kept else None, cache=relaxation_cache)
            for j, w in enumerate(self._relaxation_weight_names()):
                cols[w] = R[j][rows] if at_rows and not kept else R[j]
        if self.has("creep"):
            cols["creep_size"] = self._creep_column(rows if at_rows else n, dt, nonlinear["creep_time"], t0)
        if self.has("resonance"):
            actuator = [name for name in cols if name != "offset"]
            if actuator:
                phi, g0, g1 = second_order_foh(nonlinear["natural_frequency"], nonlinear["damping_ratio"], dt)
                if rows is not None and _increasing(rows):  # filtered whole, kept at the rows only
                    F = lowpass2_columns_at(TypedList([np.ascontiguousarray(cols[c], dtype=float) for c in actuator]),
                                            phi, g0, g1, np.ascontiguousarray(rows, dtype=np.int64))
                    filtered = dict(zip(actuator, F))
                    return {k: filtered[k] if k in filtered else v[rows] for k, v in cols.items()}
                F = lowpass2_rows(np.ascontiguousarray(np.stack([cols[c] for c in actuator])), phi, g0, g1)
                for j, c in enumerate(actuator):
                    cols[c] = F[j]
        if rows is not None and not at_rows:
            cols = {k: v[rows] for k, v in cols.items()}
        return cols


def _kept(cache: MutableMapping | None, key, make):
    """``make()``, kept in the caller's ``cache`` under ``key``: the ``KEPT`` most recently used (memory)."""
    if cache is None:
        return make()
    value = cache.pop(key) if key in cache else make()
    cache[key] = value
    while len(cache) > KEPT:
        cache.pop(next(iter(cache)))
    return value


def _increasing(rows: np.ndarray) -> bool:
    """Whether sample indices are distinct and in order (what the row-kept filter needs)."""
    rows = np.asarray(rows)
    return rows.ndim == 1 and rows.size > 0 and bool(np.all(np.diff(rows) > 0)) and int(rows[0]) >= 0


def factory(base: str, components: Sequence[str]):
    """A registry factory for ``base+components`` (hyperparameters may repeat base/components)."""

    def make(**hyper):
        hyper = dict(hyper)
        given_base = hyper.pop("base", base)
        given = hyper.pop("components", components)
        if isinstance(given, str) or not isinstance(given, (list, tuple, set, frozenset)):
            raise ModelError(f"model {extended_name(base, components)!r}: components must be a list of names, "
                             f"got {given!r}")
        given = tuple(given)
        if given_base != base or sorted(map(str, given)) != sorted(components):
            raise ModelError(f"model {extended_name(base, components)!r} cannot be built with base {given_base!r} "
                             f"and components {list(given)!r}")
        return ExtendedModel(base=base, components=tuple(components), **hyper)

    make.hyperparameter_names = ExtendedModel._hyperparameter_names()
    return make


def register_extensions(base: str, in_matrix: tuple[str, ...] = ()) -> list[str]:
    """Register ``base+cause`` for every cause (those not yet registered); returns the names.

    Only the causes in ``in_matrix`` join the default benchmark matrix.
    """
    names = []
    for cause in CAUSES:
        name = extended_name(base, (cause,))
        if not is_registered(name):
            register(name, factory(base, (cause,)), in_matrix=cause in in_matrix)
        names.append(name)
    return names
