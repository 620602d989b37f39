"""Causal steppers: a model advanced one sample at a time, its state kept between calls.

A controller runs a model at its sample rate: it hands over one input, gets one output,
and keeps the model's state for the next sample. Every registered model gives one:

    s = model.stepper(dt, params, input_range=None)   # a ``Stepper``
    y = s.step(u)          # the output at this sample for input u (float -> float)
    s.reset()              # back to the state before the first sample
    snapshot = s.state     # a plain value (dict of floats, ints and lists of floats; JSON-serialisable)
    s.set_state(snapshot)  # continue from a snapshot (of a stepper of the same model and parameters)
    y_all = s.run(u_array) # step through a whole array (convenience; same as a loop over ``step``)

Stepping through a record from ``reset`` gives the model's ``simulate`` on that record
(tests/test_stepper.py checks every registered model). ``input_range`` fixes the structure
that batch simulation takes from the record itself when none is given (play thresholds, a
Preisach grid): a stepper never sees the whole record, so it needs the range up front; a
fitted model (``FittedModel``) carries its identification records' range. Models whose
structure depends on the input range refuse a stepper without one.

An inverse stepper (``model.inverse_stepper(dt, params, input_range=None, input_limits=None)``)
has the same API with ``step(y_ref) -> u``: the input that makes the model output y_ref at
this sample, within the input limits; ``clipped`` says whether the last sample missed its
reference (the reference was out of reach) and ``n_clipped`` counts those since ``reset``.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ModelError


class Stepper:
    """A model advanced one sample at a time (see the module docstring).

    Subclasses implement ``step``, ``reset``, the ``state`` property and ``set_state``;
    ``run`` loops over ``step``."""

    #: the sample time (s) the stepper advances by
    dt: float

    def step(self, u: float) -> float:
        """The model's output at this sample for input ``u``; the state advances to it."""
        raise NotImplementedError

    def reset(self) -> None:
        """Back to the state before the first sample (as ``simulate`` starts a record)."""
        raise NotImplementedError

    @property
    def state(self) -> dict:
        """A snapshot of the state: a plain dict (floats, ints, lists of floats), JSON-serialisable."""
        raise NotImplementedError

    def set_state(self, state: dict) -> None:
        """Continue from a snapshot taken with ``state`` (of a stepper of the same model and parameters)."""
        raise NotImplementedError

    def run(self, values) -> np.ndarray:
        """``step`` over every value of a 1-D array, in order; returns the outputs."""
        values = np.asarray(values, dtype=float).ravel()
        return np.array([self.step(float(v)) for v in values])


class InverseStepper(Stepper):
    """An inverse model advanced one sample at a time: ``step(y_ref) -> u`` (see the module docstring)."""

    #: whether the last ``step`` missed its reference (out of reach within the input limits)
    clipped: bool = False
    #: how many samples missed their reference since ``reset``
    n_clipped: int = 0


def check_step_input(owner: str, value) -> float:
    """One finite sample (a float); ModelError otherwise."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ModelError(f"{owner}: a step takes one number, got {value!r}") from None
    if not math.isfinite(x):
        raise ModelError(f"{owner}: a step's input must be finite, got {x!r}")
    return x


def check_state_keys(owner: str, state, keys) -> dict:
    """A snapshot with exactly ``keys``; ModelError naming what is missing or unknown."""
    if not isinstance(state, dict):
        raise ModelError(f"{owner}: a state is a dict, got {type(state).__name__}")
    missing = sorted(set(keys) - set(state))
    unknown = sorted(set(state) - set(keys))
    if missing or unknown:
        raise ModelError(f"{owner}: state keys do not match (missing {missing}, unknown {unknown})")
    return state


class ReplayStepper(Stepper):
    """The causal stepper of a model that has no per-sample update of its own: it keeps the
    inputs since ``reset`` and returns the last sample of ``simulate`` over them.

    Exact by construction (the output at sample k is the model's output for the inputs up to
    k) but its cost grows with the record (O(k) per step): fit for tests, offline loops and
    short records, not for a real-time target. Models whose output at a sample depends on later
    inputs (a centred or smoothed derivative) refuse it (``causal_reason``)."""

    def __init__(self, model, dt: float, params, input_range):
        if input_range is None:
            raise ModelError(f"model {model.name!r}: a stepper needs the input range that fixes the model's "
                             "structure (the fit's input_range)")
        lo, hi = map(float, input_range)
        self.model = model
        self.dt = float(dt)
        self.params = model.pack(params) if isinstance(params, dict) else np.asarray(params, dtype=float)
        self.input_range = (lo, hi)
        self._inputs: list[float] = []

    def step(self, u: float) -> float:
        self._inputs.append(check_step_input(self.model.name, u))
        y = self.model.simulate(np.array(self._inputs), self.dt, self.params, input_range=self.input_range)
        return float(y[-1])

    def reset(self) -> None:
        self._inputs = []

    @property
    def state(self) -> dict:
        return {"inputs": list(self._inputs)}

    def set_state(self, state: dict) -> None:
        state = check_state_keys(self.model.name, state, ("inputs",))
        self._inputs = [float(v) for v in state["inputs"]]


def stepper_input_range(model, input_range) -> tuple[float, float]:
    """The (u_min, u_max) a stepper fixes its structure with; ModelError when it is missing or empty."""
    if input_range is None:
        raise ModelError(f"model {model.name!r}: a stepper needs the input range that fixes the model's "
                         "structure (the fit's input_range)")
    lo, hi = map(float, input_range)
    if not (math.isfinite(lo) and math.isfinite(hi) and hi > lo):
        raise ModelError(f"model {model.name!r}: a stepper needs an input range of positive width, got "
                         f"({lo!r}, {hi!r})")
    return lo, hi


class ArrayStepper(Stepper):
    """Base of the constant-time steppers whose state is one float array that the model's jitted
    per-sample function (the one its batch kernel runs) updates in place.

    Subclasses call ``_setup(model, dt, fields)`` with ``fields`` the (name, size) pairs laid out
    in that array (size 0: a scalar, a float in ``state``; else a list of floats), and implement
    ``_rest()`` (the array before the first sample) and ``_advance(u) -> y``."""

    def _setup(self, model, dt: float, fields) -> None:
        if not (dt > 0 and math.isfinite(dt)):
            raise ModelError(f"model {model.name!r}: time step must be positive, got {dt!r}")
        self.model = model
        self.dt = float(dt)
        self._fields = tuple((name, int(size)) for name, size in fields)
        self._state = np.zeros(sum(max(size, 1) for _, size in self._fields))

    def _rest(self) -> np.ndarray:
        raise NotImplementedError

    def _advance(self, u: float) -> float:
        raise NotImplementedError

    def _valid(self, array: np.ndarray) -> bool:
        """Whether a snapshot's array is a state this model can be in (default: all finite)."""
        return bool(np.all(np.isfinite(array)))

    def reset(self) -> None:
        self._state[:] = self._rest()

    def step(self, u: float) -> float:
        try:
            u = float(u)
        except (TypeError, ValueError):
            check_step_input(self.model.name, u)  # raises the one-line ModelError
        if u - u != 0.0:  # NaN or inf (cheaper than math.isfinite on a hot path)
            check_step_input(self.model.name, u)
        return self._advance(u)

    @property
    def state(self) -> dict:
        out, o = {}, 0
        for name, size in self._fields:
            if size == 0:
                out[name] = float(self._state[o])
                o += 1
            else:
                out[name] = [float(v) for v in self._state[o:o + size]]
                o += size
        return out

    def set_state(self, state: dict) -> None:
        name = self.model.name
        state = check_state_keys(name, state, [f for f, _ in self._fields])
        parts = []
        for field, size in self._fields:
            try:
                value = np.array(state[field], dtype=float).reshape(-1)
            except (TypeError, ValueError):
                raise ModelError(f"{name}: state field {field!r} must be numbers, got {state[field]!r}") from None
            if value.size != max(size, 1) or (size == 0 and np.ndim(state[field]) != 0):
                raise ModelError(f"{name}: state field {field!r} holds {value.size} values, this stepper "
                                 f"{'one number' if size == 0 else size}")
            parts.append(value)
        new = np.concatenate(parts)
        if not self._valid(new):
            raise ModelError(f"{name}: a state holds values this model cannot be in (non-finite)")
        self._state[:] = new


class ArrayInverseStepper(ArrayStepper, InverseStepper):
    """An ``ArrayStepper`` of an inverse: ``reset`` also clears ``clipped`` and ``n_clipped``, and the
    state snapshot carries ``n_clipped`` beside the array's fields. Subclasses' ``_advance(y_ref)``
    sets ``clipped`` and counts it."""

    def reset(self) -> None:
        super().reset()
        self.clipped = False
        self.n_clipped = 0

    @property
    def state(self) -> dict:
        return dict(super().state, n_clipped=int(self.n_clipped))

    def set_state(self, state: dict) -> None:
        if not isinstance(state, dict) or "n_clipped" not in state:
            raise ModelError(f"{self.model.name}: state keys do not match (missing ['n_clipped'])")
        super().set_state({k: v for k, v in state.items() if k != "n_clipped"})
        self.n_clipped = int(state["n_clipped"])
