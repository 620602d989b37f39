"""The compensators: a static linear gain (no model), a model's inverse, a PI loop.

* ``LinearGain``: y = K u + c fitted by least squares on the identification records'
  scored windows (the samples ``identify`` fits); its inverse u = (r - c) / K.
* ``ModelInverse``: a model identified with ``hysbench.identification.identify`` and
  inverted (``HysteresisModel.invert``: causal, numerical, searched within the plant's
  input limits; every model the registry can invert, P-I family or not; classical P-I with poly_order 1 uses its analytic inverse when the
  loading curve increases, else the numerical one; ``viscoelastic``, the plant's own
  equations with identified parameters, is inverted through its physics kernel,
  ``dea_physics.invert_stretch``).
  The numerical inverse's input rate is limited to ``RATE_FACTOR`` x the fastest input
  rate of the identification records (2 x 6.3 kV/s on the default dataset): a
  rate-dependent model is identified only over the rates it saw (see models/inverse.py).
  The rate-independent models inverted by their own step kernels (``RATE_FREE``:
  elliptical, dual-polynomial, preisach, bouc-wen) get no rate limit: their output depends
  on the input's path only, so no rate leaves what they were identified on, and a limit traps
  the inverse, which takes the nearest output within reach: on a Preisach stair every input
  within one rate-limited step gives the same output, so the input never leaves it; at the
  ellipse's crest near the range's ends the output falls both ways before it rises (measured:
  the 0.1 Hz sine's inverse stuck at 0.52 kV, 99 % of its samples clipped, against none
  clipped in the scored window without the limit).
* ``PI``: kp e + ki int e at a stated bandwidth: ki = 2 pi f_bw / K (integral crossover
  of the loop K/s), kp = ki tau_z with the zero at the plant's fastest response mode
  (tau_z = 16 ms, the virtual DEA's fast mode at 1.5 kV in truth.json): nominal at the
  linear gain K; the Maxwell stress makes the real small-signal gain grow with the voltage.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from hysbench.data.dataset import Dataset
from hysbench.identification.api import identify
from hysbench.identification.fit import Fit
from hysbench.models import ClassicalPI, Viscoelastic, get_model
from hysbench.models.errors import HysbenchError, ModelError
from hysbench.models.inverse import INVERSES, Inversion, StepInvertible

PI_BANDWIDTH_HZ = 5.0
PI_ZERO_S = 0.016
RATE_FACTOR = 2.0
RATE_FREE = ("elliptical", "dual-polynomial", "preisach", "bouc-wen")


@dataclass(frozen=True)
class LinearGain:
    gain: float  # K, output per input unit
    offset: float  # c

    @classmethod
    def fit(cls, dataset: Dataset) -> "LinearGain":
        records = [r for r in dataset.records if r.role == "identification"]
        u = np.concatenate([r.u[r.scored] for r in records])
        y = np.concatenate([r.y[r.scored] for r in records])
        (gain, offset), *_ = np.linalg.lstsq(np.stack([u, np.ones_like(u)], axis=1), y, rcond=None)
        if not gain > 0:
            raise HysbenchError(f"linear gain fitted on {dataset.name!r} is not positive ({gain:.4g})")
        return cls(float(gain), float(offset))

    def invert(self, reference: np.ndarray) -> Inversion:
        u = (np.asarray(reference, dtype=float) - self.offset) / self.gain
        return Inversion(u, np.zeros(u.size, dtype=bool), method="linear")


@dataclass(frozen=True)
class PI:
    kp: float
    ki: float
    bandwidth_hz: float
    zero_s: float

    @classmethod
    def design(cls, gain: float, bandwidth_hz: float = PI_BANDWIDTH_HZ, zero_s: float = PI_ZERO_S) -> "PI":
        if not (bandwidth_hz > 0 and zero_s >= 0 and gain > 0):
            raise HysbenchError(f"PI: bandwidth and gain must be positive, got {bandwidth_hz!r} Hz, {gain!r}")
        ki = 2.0 * np.pi * bandwidth_hz / gain
        return cls(kp=ki * zero_s, ki=ki, bandwidth_hz=bandwidth_hz, zero_s=zero_s)


class InverseNotRunnable(ModelError):
    """The identified model cannot run the causal inverse asked for (``ModelInverse.identify``)."""


@dataclass
class ModelInverse:
    """A model identified on a dataset, ready to invert references."""

    name: str
    fit: Fit
    inverse: str  # "analytic", "numerical (exact)", "numerical (reference-driven)" (models/inverse.py), "numerical"
    identify_seconds: float
    max_rate: float | None  # the numerical inverse's |du/dt| limit (input units per second; None: none)
    identify_options: dict = field(default_factory=dict)
    causal_inverse: str | None = None  # the P-I family's causal inverse that runs ("exact", "reference-driven")

    @classmethod
    def identify(cls, name: str, dataset: Dataset, method: str = "auto", seed: int = 0,
                 u_limits=(0.5, 2.5), inverse: str = "auto", **options) -> "ModelInverse":
        """``options``: the identifier's options (``identify``'s keyword arguments). ``inverse``: the
        P-I family's causal inverse (``models.inverse.INVERSES``; other models ignore it): "auto"
        takes classical P-I's analytic inverse where it applies, else ``resolve_inverse``'s choice;
        "exact" or "reference-driven" runs that numerical inverse (a fit it cannot run on raises
        ``InverseNotRunnable``, after the identification)."""
        check_inverse_option(inverse)
        model = get_model(name)
        if model.inverse_unavailable:
            raise ModelError(f"model {name!r} cannot be inverted: {model.inverse_unavailable}")
        t0 = time.perf_counter()
        fit = identify(model, dataset, method=method, seed=seed, **options)
        seconds = time.perf_counter() - t0
        label = "numerical (physics kernel)" if isinstance(model, Viscoelastic) else "numerical"
        chosen = None
        if isinstance(model, StepInvertible):  # the P-I family: which causal inverse runs
            dt = dataset.records[0].dt
            try:
                chosen, _ = model.resolve_inverse(inverse, model._structure(dt, fit.params, fit.input_range, 1),
                                                  fit.input_range)
            except ModelError as err:
                raise InverseNotRunnable(str(err)) from None
            label = f"numerical ({chosen})"
        if inverse == "auto" and isinstance(model, ClassicalPI) and model.poly_order == 1:
            try:
                model.invert_analytic(np.zeros(2), 1e-3, fit.params, fit.input_range)
                label, chosen = "analytic", None
            except ModelError:
                pass  # loading curve not increasing: the numerical inverse (it counts where it clips)
        rates = [np.max(np.abs(np.diff(r.u))) / r.dt for r in dataset.records if r.role == "identification"]
        max_rate = None if name in RATE_FREE else RATE_FACTOR * float(max(rates))
        return cls(name, fit, label, seconds, max_rate, dict(options), chosen)

    def invert(self, reference: np.ndarray, dt: float, u_limits) -> Inversion:
        model = self.fit.model_instance()
        if self.inverse == "analytic":
            return model.invert_analytic(reference, dt, self.fit.params, self.fit.input_range)
        which = {} if self.causal_inverse is None else {"inverse": self.causal_inverse}
        return model.invert(reference, dt, self.fit.params, input_range=self.fit.input_range, input_limits=u_limits,
                            max_rate=self.max_rate, u_start=u_limits[0], **which)


def check_inverse_option(inverse) -> str:
    """The P-I family's inverse option (``INVERSES``), refused in one line otherwise."""
    if inverse not in INVERSES:
        raise HysbenchError(f"inverse must be one of {', '.join(INVERSES)}; got {inverse!r}")
    return inverse
