"""The common model interface.

A model is configured by explicit constructor arguments (its hyperparameters,
as in scikit-learn) and evaluated with a separate parameter set: a mapping
name -> value, or, in the batched form, an array of shape (n_sets, n_params)
whose columns follow ``model.param_names``.

Every model declares its named parameters with default bounds and says which
enter the output linearly. For models linear in part of their parameters,
``regressors`` returns the matrix Phi with y = Phi @ theta_linear, given the
nonlinear parameters, so identifiers can solve that part exactly.

``input_range`` (u_min, u_max) fixes input-dependent structure such as play
thresholds or a Preisach grid. Left as None, it is taken from the simulated
input itself; identifiers pass the range of the identification records so
that a fitted model is one fixed operator on every record.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass, replace
from typing import ClassVar, Mapping, Sequence

import numpy as np

from .errors import ModelError
from .kernels import all_finite
from .stepper import InverseStepper, ReplayStepper, Stepper
from .units import render
from .window import Window


@dataclass(frozen=True)
class Parameter:
    """A named parameter with default search bounds (lmfit style)."""

    name: str
    value: float
    min: float
    max: float
    linear: bool = False
    description: str = ""
    log_scale: bool = False  # positive and spanning decades: searched on a log scale
    unit: str | None = None  # models/units.py: "y/u", "s", "1" (dimensionless); None: not declared

    def scaled(self, factor: float) -> "Parameter":
        """Bounds and default multiplied by a positive factor (unit scaling)."""
        return replace(self, value=self.value * factor, min=self.min * factor, max=self.max * factor)


@dataclass(frozen=True)
class DataScale:
    """Typical magnitudes of the data, used to scale default bounds.

    ``u`` is max |input|, ``y`` is max |output|, ``time`` a characteristic time
    in seconds (the shortest drive period). The defaults are the paper's DEA.
    """

    u: float = 2.5
    y: float = 10.0
    time: float = 1.0

    @classmethod
    def of(cls, inputs: Sequence[np.ndarray], outputs: Sequence[np.ndarray], time: float = 1.0) -> "DataScale":
        u = max(float(np.max(np.abs(x))) for x in inputs)
        y = max(float(np.max(np.abs(x))) for x in outputs)
        return cls(u=u if u > 0 else 1.0, y=y if y > 0 else 1.0, time=time)


class HysteresisModel:
    """Base class. Subclasses set ``name`` and implement ``parameters`` and
    ``simulate_batch``; partly linear models also implement ``regressors``."""

    name: ClassVar[str] = ""
    presets_available: ClassVar[tuple[str, ...]] = ()

    # --- configuration -------------------------------------------------
    @classmethod
    def _hyperparameter_names(cls) -> list[str]:
        sig = inspect.signature(cls.__init__)
        return [p for p in sig.parameters if p != "self"]

    def get_hyperparameters(self) -> dict:
        """The constructor arguments, as given (scikit-learn's get_params)."""
        return {k: getattr(self, k) for k in self._hyperparameter_names()}

    def clone(self, **changes) -> "HysteresisModel":
        """A new model of the same class, with some hyperparameters changed."""
        hyper = self.get_hyperparameters()
        hyper.update(changes)
        return type(self)(**hyper)

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_hyperparameters().items())
        return f"{type(self).__name__}({args})"

    # --- parameters ------------------------------------------------------
    def parameters(self, scale: DataScale | None = None) -> tuple[Parameter, ...]:
        """Named parameters with default bounds, scaled to the data's units (cached per scale)."""
        scale = scale or DataScale()
        cache = self.__dict__.setdefault("_parameter_cache", {})
        params = cache.get(scale)
        if params is None:
            params = cache[scale] = tuple(self.declare_parameters(scale))
        return params

    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        """The parameters for this data scale; subclasses implement this, callers use ``parameters``."""
        raise NotImplementedError

    @staticmethod
    def offset_parameter(scale: DataScale, bound: float = 2.0) -> Parameter:
        """The output offset every model may carry: |c| <= bound * max |y|."""
        b = bound * scale.y
        return Parameter("offset", 0.0, -b, b, True, "output offset (sensor zero)", unit="y")

    @property
    def param_names(self) -> tuple[str, ...]:
        names = self.__dict__.get("_param_names")  # cached like ``parameters``: hyperparameters are fixed
        if names is None:
            names = self.__dict__["_param_names"] = tuple(p.name for p in self.parameters())
        return names

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    @property
    def linear_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters() if p.linear)

    @property
    def nonlinear_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters() if not p.linear)

    def parameter_units(self, input_unit: str = "", output_unit: str = "") -> dict[str, str]:
        """Each parameter's unit in the data's units, e.g. {"a1": "mm/kV"} (models/units.py; "" for a dimensionless
        one and for one whose model declares no unit, as a user's own model may not)."""
        return {p.name: render(p.unit, input_unit, output_unit) if p.unit is not None else ""
                for p in self.parameters()}

    @property
    def has_linear_part(self) -> bool:
        return bool(self.linear_names) and type(self).regressors is not HysteresisModel.regressors

    def bounds(self, scale: DataScale | None = None) -> tuple[np.ndarray, np.ndarray]:
        params = self.parameters(scale)
        return np.array([p.min for p in params]), np.array([p.max for p in params])

    def default_params(self, scale: DataScale | None = None) -> dict[str, float]:
        return {p.name: p.value for p in self.parameters(scale)}

    def start_from_data(self, records: Sequence[tuple], scale: DataScale) -> tuple[dict, dict] | None:
        """(start, bounds) computed from the fit records, each given as (u, y, dt, window), for models
        whose parameters' magnitudes the data scale alone cannot set (an oscillator's mass); None (the
        default): the model's default parameters and bounds. Identifiers use it unless the user gives
        a start or bounds."""
        return None

    def preset(self, name: str) -> dict[str, float]:
        """A named parameter set (e.g. 'paper'); 'default' is always there."""
        if name == "default":
            return self.default_params()
        raise ModelError(
            f"model {self.name!r} has no preset {name!r}; presets: {', '.join(('default',) + self.presets_available)}"
        )

    def pack(self, params: Mapping[str, float]) -> np.ndarray:
        """Parameter mapping -> vector in ``param_names`` order."""
        names = self.param_names
        unknown = sorted(set(params) - set(names))
        missing = [n for n in names if n not in params]
        if unknown or missing:
            parts = []
            if missing:
                parts.append(f"missing {', '.join(missing)}")
            if unknown:
                parts.append(f"unknown {', '.join(unknown)}")
            raise ModelError(f"parameters for model {self.name!r}: {'; '.join(parts)}")
        return np.array([float(params[n]) for n in names])

    def unpack(self, vector: np.ndarray) -> dict[str, float]:
        vector = np.asarray(vector, dtype=float)
        return dict(zip(self.param_names, (float(v) for v in vector)))

    # --- evaluation ------------------------------------------------------
    def simulate(self, u, dt: float, params: Mapping[str, float] | np.ndarray, input_range=None) -> np.ndarray:
        """Output for a 1-D input sampled every ``dt`` seconds."""
        if isinstance(params, np.ndarray):  # first: cheaper than the Mapping (abstract class) test
            vec = params.astype(float, copy=False)
        else:
            vec = self.pack(params) if isinstance(params, Mapping) else np.asarray(params, dtype=float)
        return self.simulate_batch(u, dt, vec[None, :], input_range=input_range)[0]

    def simulate_batch(self, u, dt: float, param_sets: np.ndarray, input_range=None) -> np.ndarray:
        """Outputs for many parameter sets, shape (n_sets, n_samples)."""
        raise NotImplementedError

    def simulate_window_batch(self, u, dt: float, param_sets: np.ndarray, window,
                              input_range=None) -> np.ndarray:
        """Samples ``window`` of ``simulate_batch`` (the model still runs from the first
        sample), shape (n_sets, n_window). A window is a slice with step 1 or increasing
        sample indices (see ``_window_bounds``). Identifiers score only a record's window;
        models with long records override this to store only those samples."""
        index = Window.of(window, np.size(u), self.name).index
        return np.ascontiguousarray(self.simulate_batch(u, dt, param_sets, input_range=input_range)[:, index])

    def regressors(self, u, dt: float, nonlinear: Mapping[str, float], input_range=None) -> np.ndarray:
        """Phi with y = Phi @ [linear parameters in ``linear_names`` order]."""
        raise ModelError(f"model {self.name!r} has no linear part to solve exactly")

    def windowed_regressors(self, u, dt: float, nonlinear: Mapping[str, float], window,
                            input_range=None) -> np.ndarray:
        """Rows ``window`` of ``regressors`` (the model still runs from the first sample); a
        window is a slice with step 1 or increasing sample indices.

        Identifiers fit only a record's scored window; models with long
        records override this to avoid building the full matrix.
        """
        index = Window.of(window, np.size(u), self.name).index
        return np.ascontiguousarray(self.regressors(u, dt, nonlinear, input_range=input_range)[index])

    def windowed_regressors_batch(self, u, dt: float, nonlinear_sets: np.ndarray, window,
                                  input_range=None) -> np.ndarray:
        """``windowed_regressors`` for many nonlinear parameter sets (columns in
        ``nonlinear_names`` order); shape (n_sets, n_rows, n_linear)."""
        names = self.nonlinear_names
        sets = np.asarray(nonlinear_sets, dtype=float)
        sets = sets.reshape(1, -1) if sets.ndim < 2 else sets
        return np.stack([self.windowed_regressors(u, dt, dict(zip(names, (float(v) for v in row))), window,
                                                  input_range=input_range) for row in sets])

    # --- inverse (see models/inverse.py) --------------------------------
    inverse_unavailable: ClassVar[str | None] = "no causal inverse is implemented for this model"

    def invert(self, y_desired, dt: float, params, input_range=None, input_limits=None):
        """The input that makes the model output ``y_desired`` (an ``inverse.Inversion``); models
        that cannot be inverted raise ModelError naming ``inverse_unavailable``."""
        raise ModelError(f"model {self.name!r} cannot be inverted: {self.inverse_unavailable}")

    # --- causal steppers (models/stepper.py) ----------------------------
    @property
    def noncausal_reason(self) -> str | None:
        """Why the output at a sample depends on later inputs (then no stepper exists), or None."""
        derivative = getattr(self, "derivative", "backward")
        if derivative != "backward":
            return (f"its {derivative!r} derivative uses later samples, so the output at a sample is not a "
                    "function of the inputs up to it (use derivative='backward')")
        return None

    def stepper(self, dt: float, params, input_range=None) -> Stepper:
        """A causal ``Stepper`` of this model at sample time ``dt`` (models/stepper.py). The base
        class gives a ``ReplayStepper`` (exact, O(k) per step); models with a per-sample update
        override this with a constant-time one."""
        self._check_causal()
        return ReplayStepper(self, dt, params, input_range)

    def inverse_stepper(self, dt: float, params, input_range=None, input_limits=None, **options) -> InverseStepper:
        """A causal ``InverseStepper``: ``step(y_ref) -> u`` (models that cannot be inverted raise)."""
        raise ModelError(f"model {self.name!r} cannot be inverted: {self.inverse_unavailable}")

    def _check_causal(self) -> None:
        reason = self.noncausal_reason
        if reason:
            raise ModelError(f"model {self.name!r} has no causal stepper: {reason}")

    # --- helpers for subclasses -----------------------------------------
    def _check_input(self, u, dt: float) -> np.ndarray:
        u = np.ascontiguousarray(u, dtype=float)
        if u.ndim != 1 or u.size == 0:
            raise ModelError(f"model {self.name!r} needs a non-empty 1-D input, got shape {u.shape}")
        if not all_finite(u):
            raise ModelError(f"model {self.name!r}: input holds NaN or inf")
        if not (dt > 0 and math.isfinite(dt)):
            raise ModelError(f"model {self.name!r}: time step must be positive, got {dt!r}")
        return u

    def _check_param_sets(self, param_sets) -> np.ndarray:
        P = param_sets
        if not (isinstance(P, np.ndarray) and P.ndim == 2 and P.dtype == np.float64 and P.flags.c_contiguous):
            P = np.ascontiguousarray(np.atleast_2d(np.asarray(param_sets, dtype=float)))
        if P.ndim != 2 or P.shape[1] != self.n_params:
            raise ModelError(
                f"model {self.name!r} takes {self.n_params} parameters ({', '.join(self.param_names)}), "
                f"got an array of shape {np.shape(param_sets)}"
            )
        return P

    def _window(self, u: np.ndarray, window) -> Window:
        """The checked ``Window`` of a record of u's length (from a Window, a slice or row indices)."""
        return Window.of(window, u.size, self.name)

    def _window_bounds(self, u: np.ndarray, window) -> tuple[int, int]:
        """(start, stop): the samples a window spans."""
        w = self._window(u, window)
        return w.start, w.stop

    def _window_rows(self, u: np.ndarray, window) -> np.ndarray | None:
        """A row-subset window's sample indices, or None for a contiguous window."""
        return self._window(u, window).rows

    def _in_span(self, u: np.ndarray, window, start: int):
        """What to take from an array computed over a window's span [start, stop)."""
        w = self._window(u, window)
        return slice(None) if w.rows is None else w.rows - start

    @staticmethod
    def _input_range(u: np.ndarray, input_range) -> tuple[float, float]:
        if input_range is None:
            return float(np.min(u)), float(np.max(u))
        lo, hi = input_range
        return float(lo), float(hi)
