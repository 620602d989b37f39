"""A fitted candidate cause, its parameters in the report's vocabulary, and small search helpers.

Screen-internal comparisons (the relaxation order, the first-order pre-checks,
the library screen's number of terms) use BIC from
``hysbench.identification.criteria`` with the AR(1) effective sample size of
the base model's residual (``n_effective``): model error is smooth and 10,000
residual rows carry far fewer independent pieces of information. The cause is
never chosen by BIC: see ``selection`` (held-out prediction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from scipy.ndimage import uniform_filter1d

from hysbench.identification.criteria import bic
from hysbench.models.base import HysteresisModel

MAX_ROWS = 10_000  # rows per record in the screen
MAX_RELAXATION = 4
LOG_SCALE = ("tau", "creep_time", "natural_frequency", "damping_ratio")
NO_CUT = ("the level cuts too few samples of the prediction (policy min_clipped_samples): not a clip (what it gains "
          "comes from "
          "leaving the output's extreme samples out of the fit)")  # a saturation's limit (``Screen.limit_of``)
DRIVE_LOCKED = ("at a drive harmonic with the same phase in every record: a misfit locked to the drive, "
                "not a disturbance of its own")  # an interference's limit (``Screen.limit_of``)


@dataclass
class Candidate:
    """One fitted candidate: a cause's extension (or the null) on the screen's rows."""

    cause: str
    label: str
    model: HysteresisModel
    params: dict  # every parameter of ``model``
    k: int  # free parameters
    rss: float
    n: int
    estimates: dict = field(default_factory=dict)  # the cause's parameters in report units
    n_effective: float | None = None  # AR(1) effective sample size of the null's residual
    bic: float = math.nan
    delta_bic: float = math.nan  # against the null (effective sample size)
    explained: float = math.nan  # share of the null's identification RSS explained (in-sample)
    validation_rss: float = math.nan
    hyperparameters: dict = field(default_factory=dict)
    stage: str = "joint"  # "fixed base": the base's nonlinear parameters held at the null's
    limit: str = ""  # why the candidate cannot be named (a parameter at the vocabulary's limit), if so
    heldout: dict = field(default_factory=dict)  # leave-one-record-out prediction (``selection``)
    uncertainty: dict = field(default_factory=dict)  # spread of each estimate over the folds
    clips: "Candidate | None" = None  # saturation on top of a kept part: that part (None: the base)
    train_residuals: list | None = field(default=None, repr=False)  # per fold: the residual on its training rows

    def __post_init__(self):
        self.bic = bic(self.rss, self.n, self.k, self.n_effective) if self.rss > 0 else -math.inf

    @property
    def heldout_gain(self) -> float:
        return float(self.heldout.get("gain", math.nan))

    def summary(self) -> dict:
        model = self.model.name + ("+saturation" if self.clips is not None else "")  # a clip: of that model
        return {"cause": self.cause, "label": self.label, "model": model, "stage": self.stage,
                "admissible": not self.limit, "limit": self.limit, "k": self.k,
                "bic_effective": self.bic, "delta_bic_effective": self.delta_bic, "rss": self.rss, "n_rows": self.n,
                "n_effective": self.n_effective, "explained_identification": self.explained, "heldout": self.heldout,
                "estimates": self.estimates, "uncertainty": self.uncertainty}


def estimates_of(cause: str, params: Mapping[str, float], model: HysteresisModel) -> dict:
    """A cause's parameters in the report's vocabulary."""
    if cause == "relaxation":
        k = getattr(model, "n_relaxation", 0)
        taus = sorted(float(params[f"tau{i}"]) for i in range(1, k + 1))
        return {"tau_s": taus}
    if cause == "delay":
        return {"delay_s": float(params["delay"])}
    if cause == "resonance":
        return {"natural_frequency_hz": float(params["natural_frequency"]),
                "damping_ratio": float(params["damping_ratio"])}
    if cause == "creep":
        return {"size": float(params["creep_size"]), "time_scale_s": float(params["creep_time"])}
    if cause == "interference":
        out = {"frequency_hz": float(params["interference_frequency"])}
        if "interference_amplitude" in params:  # one phase per record (``interference``)
            out["amplitude"] = float(params["interference_amplitude"])
        else:
            out["amplitude"] = math.hypot(float(params["interference_sin"]), float(params["interference_cos"]))
        return out
    if cause == "saturation":
        return {"level": float(params["saturation_level"]), "side": getattr(model, "saturation_side", "upper")}
    return {}


def is_log(name: str) -> bool:
    return any(name.startswith(s) for s in LOG_SCALE)


def local_minima(vals: np.ndarray, n: int) -> list[int]:
    """Indices of the n lowest local minima of a sampled curve (ends included)."""
    v = np.asarray(vals, dtype=float)
    if v.size < 3:
        return [int(np.argmin(v))]
    left = np.r_[True, v[1:] <= v[:-1]]
    right = np.r_[v[:-1] <= v[1:], True]
    idx = np.flatnonzero(left & right)
    return [int(i) for i in idx[np.argsort(v[idx])][:n]]


def prominence(amp: np.ndarray, half_width: int = 50) -> np.ndarray:
    """A spectrum over its running geometric mean (a peak stands out of its neighbourhood, whatever
    the slope)."""
    log_amp = np.log(np.maximum(amp, 1e-300))
    return np.exp(log_amp - uniform_filter1d(log_amp, size=2 * half_width + 1, mode="nearest"))
