"""Constant-time steppers of the extended models whose blocks have no step structure of the P-I
family (``ExtendedModel``: +delay, +resonance, +saturation; and any component on a base outside the
P-I family, e.g. the diagnosis's ``bouc-wen+relaxation``).

The stepper is the model's measurement chain (extended.py's module docstring) built from
per-sample blocks around the actuator's own stepper, in the order ``simulate_batch`` applies them:

    saturation    ``ClipStepper``           the clip after the stepper inside it (as np.minimum/maximum)
    interference  ``InterferenceStepper``   the sinusoid in the record's time, added after the rest
    delay         ``DelayStepper``          a ring buffer of the last ceil(d / dt) + 1 inputs; the
                                            actuator receives them interpolated as ``delayed_input``
    resonance     ``ResonanceStepper``      ``filter_kernels.lowpass2_advance`` (the batch filter's step)
    actuator      the P-I stepper of the base with relaxation, creep and interference
                  (``pi_stepper.PIStepper``) where the base has a step structure and the actuator runs
                  in the record's time; else ``ActuatorStepper``: the base's own stepper plus the
                  relaxation bank (``filter_kernels.lowpass1_bank_advance``, the batch filter's step)
                  and the creep in the actuator's own time (t0 = the delay's fraction of a sample)

Each block's state is a fixed-size plain dict: its own fields plus the inner stepper's, prefixed
``actuator.``.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ModelError
from .filter_kernels import (first_order_foh, lowpass1_bank_advance, lowpass2_advance, lowpass2_coefficients,
                             second_order_foh)
from .inverse import StepInvertible
from .stepper import Stepper, check_state_keys, check_step_input

PREFIX = "actuator."


def delay_samples(delay: float, dt: float) -> tuple[int, float]:
    """(k0, frac0): a delay d starts the actuator at record sample k0 = ceil(d / dt) (to 1e-9 of a
    sample), frac0 = k0 - d / dt of a sample late (0 for k0 = 0); ``ExtendedModel.delayed_input``."""
    ds = delay / dt
    k0 = int(math.ceil(ds - 1e-9))
    return k0, max(k0 - ds, 0.0)


def _finite(owner: str, u) -> float:
    u = float(u) if isinstance(u, (float, int)) else check_step_input(owner, u)
    if u - u != 0.0:  # NaN or inf
        check_step_input(owner, u)
    return u


class WrappedStepper(Stepper):
    """A block around an inner stepper: its own fields (``_own_state`` / ``_set_own``) and the inner
    stepper's, prefixed ``actuator.``."""

    _own_keys: tuple[str, ...] = ()

    def __init__(self, model, inner: Stepper):
        self.model, self.inner, self.dt = model, inner, inner.dt

    def reset(self) -> None:
        self.inner.reset()
        self._reset_own()

    @property
    def state(self) -> dict:
        out = self._own_state()
        out.update({PREFIX + k: v for k, v in self.inner.state.items()})
        return out

    def set_state(self, state: dict) -> None:
        if not isinstance(state, dict):
            raise ModelError(f"{self.model.name}: a state is a dict, got {type(state).__name__}")
        own = {k: v for k, v in state.items() if not k.startswith(PREFIX)}
        check_state_keys(self.model.name, own, self._own_keys)
        before = self.inner.state
        self.inner.set_state({k[len(PREFIX):]: v for k, v in state.items() if k.startswith(PREFIX)})
        try:
            self._set_own(own)
        except ModelError:
            self.inner.set_state(before)  # a refused state changes nothing
            raise

    def _number(self, state: dict, key: str) -> float:
        try:
            value = float(state[key])
        except (TypeError, ValueError):
            raise ModelError(f"{self.model.name}: state field {key!r} must be a number, got {state[key]!r}") from None
        if not math.isfinite(value):
            raise ModelError(f"{self.model.name}: state field {key!r} must be finite, got {value!r}")
        return value

    def _count(self, state: dict, key: str) -> int:
        value = self._number(state, key)
        if value < 0 or value != int(value):
            raise ModelError(f"{self.model.name}: state field {key!r} must be a sample count, got {state[key]!r}")
        return int(value)

    def _reset_own(self) -> None:
        pass

    def _own_state(self) -> dict:
        return {}

    def _set_own(self, state: dict) -> None:
        pass


class ClipStepper(Stepper):
    """``saturation``: the inner stepper's output clipped at ``level`` from above (``upper``) or below;
    NaN stays NaN, as ``np.minimum`` / ``np.maximum`` in ``simulate_batch``. No state of its own."""

    def __init__(self, model, inner: Stepper, level: float, upper: bool):
        self.model, self.inner, self.dt = model, inner, inner.dt
        self.level, self.upper = float(level), bool(upper)

    def step(self, u: float) -> float:
        y = self.inner.step(u)
        if self.upper:
            return self.level if y > self.level else y
        return self.level if y < self.level else y

    def reset(self) -> None:
        self.inner.reset()

    @property
    def state(self) -> dict:
        return self.inner.state

    def set_state(self, state: dict) -> None:
        self.inner.set_state(state)


class InterferenceStepper(WrappedStepper):
    """``interference`` after a delay or a mode: a sin(2 pi f t_k) + b cos(2 pi f t_k) added in the
    record's time t_k = k dt (the phase computed as ``ExtendedModel.interference_columns``)."""

    _own_keys = ("k",)

    def __init__(self, model, inner: Stepper, frequency: float, sin_weight: float, cos_weight: float):
        super().__init__(model, inner)
        self._w = 2.0 * np.pi * float(frequency) * self.dt
        self._a, self._b = float(sin_weight), float(cos_weight)
        self._k = 0

    def step(self, u: float) -> float:
        y = self.inner.step(u)
        phase = self._w * float(self._k)
        self._k += 1
        return y + (self._a * math.sin(phase) + self._b * math.cos(phase))

    def _reset_own(self) -> None:
        self._k = 0

    def _own_state(self) -> dict:
        return {"k": self._k}

    def _set_own(self, state: dict) -> None:
        self._k = self._count(state, "k")


class ResonanceStepper(WrappedStepper):
    """``resonance``: the actuator's output less the base's offset through the second-order block
    (``filter_kernels.lowpass2_advance``: the step of the batch filter ``_lowpass2``), the offset added
    back. State: first, x, x' (the mode), v (the filtered signal at the last sample)."""

    _own_keys = ("first", "x", "dx", "v1")

    def __init__(self, model, inner: Stepper, natural_frequency: float, damping_ratio: float, offset: float):
        super().__init__(model, inner)
        self._coef = lowpass2_coefficients(*second_order_foh(float(natural_frequency), float(damping_ratio), self.dt))
        self._offset = float(offset)
        self._mode = np.zeros(4)
        self._reset_own()

    def step(self, u: float) -> float:
        v = self.inner.step(u) - self._offset
        return lowpass2_advance(self._mode, self._coef, v) + self._offset

    def _reset_own(self) -> None:
        self._mode[:] = (1.0, 0.0, 0.0, 0.0)

    def _own_state(self) -> dict:
        m = self._mode
        return {"first": bool(m[0] != 0.0), "x": float(m[1]), "dx": float(m[2]), "v1": float(m[3])}

    def _set_own(self, state: dict) -> None:
        # the mode's state may be NaN after a diverged actuator (as the batch filter carries it on)
        values = []
        for key in ("x", "dx", "v1"):
            try:
                values.append(float(state[key]))
            except (TypeError, ValueError):
                raise ModelError(f"{self.model.name}: state field {key!r} must be a number, got {state[key]!r}") \
                    from None
        self._mode[:] = (1.0 if state["first"] else 0.0, *values)


class DelayStepper(WrappedStepper):
    """``delay`` d: the actuator (the inner stepper) starts at record sample k0 = ceil(d / dt) and receives,
    at record sample k0 + j, the input at position j + frac0 (frac0 = k0 - d / dt; linear between
    samples, as ``ExtendedModel.delayed_input`` and ``np.interp``); before k0 the output is the base's
    rest output for the first input (``rest``, from a fresh stepper of the base). The last k0 + 1
    inputs are kept in a ring buffer. State: k (samples so far), rest, inputs (oldest first)."""

    _own_keys = ("k", "rest", "inputs")

    def __init__(self, model, inner: Stepper, rest_stepper: Stepper, delay: float):
        super().__init__(model, inner)
        self.k0, self._frac0 = delay_samples(float(delay), self.dt)
        self._rest_stepper = rest_stepper
        self._ring = [0.0] * (self.k0 + 1)
        self._reset_own()

    def _reset_own(self) -> None:
        self._k = 0
        self._rest = 0.0
        self._ring[:] = [0.0] * (self.k0 + 1)

    def step(self, u: float) -> float:
        u = _finite(self.model.name, u)
        k, k0 = self._k, self.k0
        self._k = k + 1
        if k0 == 0:
            return self.inner.step(u)
        ring = self._ring
        ring[k % (k0 + 1)] = u  # the input of record sample k
        if k == 0:
            self._rest_stepper.reset()
            self._rest = self._rest_stepper.step(u)
        if k < k0:
            return self._rest
        j = k - k0
        u_j, u_next = ring[j % (k0 + 1)], ring[(j + 1) % (k0 + 1)]
        pos = float(j) + self._frac0
        if pos == float(j):
            u_a = u_j
        elif pos >= float(j + 1):
            u_a = u_next
        else:  # np.interp's slope * (x - x_j) + y_j
            u_a = (u_next - u_j) * (pos - float(j)) + u_j
        return self.inner.step(u_a)

    def _own_state(self) -> dict:
        n, k = self.k0 + 1, self._k
        ordered = [self._ring[(k + i) % n] for i in range(n)]  # oldest first (the slot k is next to be written)
        return {"k": k, "rest": float(self._rest), "inputs": [float(v) for v in ordered]}

    def _set_own(self, state: dict) -> None:
        k = self._count(state, "k")
        rest = self._number(state, "rest")
        try:
            inputs = [float(v) for v in state["inputs"]]
        except (TypeError, ValueError):
            raise ModelError(f"{self.model.name}: state field 'inputs' must be a list of numbers") from None
        n = self.k0 + 1
        if len(inputs) != n or not all(math.isfinite(v) for v in inputs):
            raise ModelError(f"{self.model.name}: state field 'inputs' must hold {n} finite numbers, "
                             f"got {len(inputs)}")
        self._k, self._rest = k, rest
        for i, v in enumerate(inputs):
            self._ring[(k + i) % n] = v


class ActuatorStepper(WrappedStepper):
    """The actuator on a base outside the P-I family's step structure (or late, for its creep): the
    base's own stepper plus the relaxation bank, L_tau_k[u^p] weighted by c_kp
    (``filter_kernels.lowpass1_bank_advance``), and the creep s (1 - exp(-(t0 + j dt) / T_c)) at the
    actuator's sample j, added in ``_actuator_batch``'s order. State: k (the actuator's samples so
    far), relaxation ([first, the filters, u(k-1)])."""

    _own_keys = ("k", "relaxation")

    def __init__(self, model, inner: Stepper, params: dict, t0: float):
        super().__init__(model, inner)
        self._bank = model.has("relaxation")
        if self._bank:
            coef = [first_order_foh(float(params[f"tau{k}"]), self.dt) for k in range(1, model.n_relaxation + 1)]
            n_p = len(model.relaxation_powers)
            a, b0, b1 = ([c[i] for c in coef for _ in range(n_p)] for i in range(3))
            weights = [float(params[w]) for w in model._relaxation_weight_names()]
            self._coef = np.array(a + b0 + b1 + weights)
            self._powers = np.array(list(model.relaxation_powers) * len(coef), dtype=np.int64)
        else:
            self._coef, self._powers = np.zeros(0), np.zeros(0, dtype=np.int64)
        self._filters = np.zeros(self._powers.size + 2)
        self._creep = model.has("creep")
        self._creep_size = float(params.get("creep_size", 0.0))
        self._creep_time = float(params.get("creep_time", 1.0))
        self._t0 = float(t0)
        self._reset_own()

    def step(self, u: float) -> float:
        y = self.inner.step(u)
        if self._bank:
            y = y + lowpass1_bank_advance(self._filters, self._coef, self._powers, float(u))
        if self._creep:
            y = y + self._creep_size * -math.expm1(-(self._t0 + self._k * self.dt) / self._creep_time)
        self._k += 1
        return y

    def _reset_own(self) -> None:
        self._k = 0
        self._filters[:] = 0.0
        self._filters[0] = 1.0

    def _own_state(self) -> dict:
        return {"k": self._k, "relaxation": [float(v) for v in self._filters]}

    def _set_own(self, state: dict) -> None:
        k = self._count(state, "k")
        try:
            filters = np.array(state["relaxation"], dtype=float).reshape(-1)
        except (TypeError, ValueError):
            raise ModelError(f"{self.model.name}: state field 'relaxation' must be a list of numbers") from None
        if filters.size != self._filters.size or not np.all(np.isfinite(filters)):
            raise ModelError(f"{self.model.name}: state field 'relaxation' must hold {self._filters.size} finite "
                             "numbers")
        self._k = k
        self._filters[:] = filters


def build(model, components: tuple, dt: float, params: dict, input_range, t0: float = 0.0) -> Stepper:
    """The constant-time stepper of ``model`` restricted to ``components`` (a tuple in the model's
    order) with the parameters ``params`` (a dict over the model's names); ``t0``: the actuator's own
    time at its first sample (a delay's fraction of a sample)."""
    comps = tuple(components)
    base = model.base_model
    pi_base = isinstance(base, StepInvertible) and not base.inverse_unavailable

    def without(*names):
        return tuple(c for c in comps if c not in names)

    def base_stepper():
        return base.stepper(dt, {n: params[n] for n in base.param_names}, input_range)

    if "saturation" in comps:
        return ClipStepper(model, build(model, without("saturation"), dt, params, input_range, t0),
                           params["saturation_level"], model.saturation_side == "upper")
    if "interference" in comps and ("delay" in comps or "resonance" in comps or not pi_base):
        return InterferenceStepper(model, build(model, without("interference"), dt, params, input_range, t0),
                                   params["interference_frequency"], params["interference_sin"],
                                   params["interference_cos"])
    if "delay" in comps:
        k0, frac0 = delay_samples(float(params["delay"]), dt)
        late = frac0 * dt if k0 > 0 else 0.0  # the actuator's own time at its first sample (delayed_input)
        return DelayStepper(model, build(model, without("delay"), dt, params, input_range, late), base_stepper(),
                            params["delay"])
    if "resonance" in comps:
        offset = params.get("offset", 0.0) if "offset" in model.base_names else 0.0
        return ResonanceStepper(model, build(model, without("resonance"), dt, params, input_range, t0),
                                params["natural_frequency"], params["damping_ratio"], offset)
    if not comps:
        return base_stepper()
    if pi_base and not ("creep" in comps and t0 != 0.0):
        inner = model.clone(components=comps)
        return inner.stepper(dt, {n: params[n] for n in inner.param_names}, input_range)
    return ActuatorStepper(model, base_stepper(), params, t0)
