"""A fitted candidate cause (``Candidate``) and small helpers of the search. The screen compares its own fits by
BIC with the AR(1) effective sample size of the null's residual; the cause is chosen on held-out records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from scipy.ndimage import uniform_filter1d
from scipy.optimize import minimize_scalar

from hysbench.identification.criteria import bic
from hysbench.identification.linear import scaled_lstsq
from hysbench.models.base import HysteresisModel

from .cause import CAUSES, cause_of_parameter, log_scale, open_ended_parameter

MAX_ROWS = 10_000  # rows per record in the screen
MAX_RELAXATION = 4
NO_CUT = ("the level cuts too few samples of the prediction (policy min_clipped_samples): not a clip (what it gains "
          "comes from leaving the output's extreme samples out of the fit)")  # a saturation's limit
DRIVE_LOCKED = ("at a drive harmonic with the same phase in every record: a misfit locked to the drive, "
                "not a disturbance of its own")  # an interference's limit (``Screen.limit_of``)
OPEN_ENDED_NOTE = "longer than these records show, at its upper search bound: a straight drift"
is_log = log_scale  # whether a cause's parameter is searched on a log scale (``Cause.log_scale``)


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
    def kind(self):
        """Its cause (``causes.Cause``; None for the base alone)."""
        return CAUSES.get(self.cause)

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
    """A cause's parameters in the report's vocabulary (``Cause.estimates``; none for the base alone)."""
    return CAUSES[cause].estimates(params, model) if cause in CAUSES else {}


def local_minima(vals: np.ndarray, n: int) -> list[int]:
    """Indices of the n lowest local minima of a sampled curve (ends included)."""
    v = np.asarray(vals, dtype=float)
    if v.size < 3:
        return [int(np.argmin(v))]
    left = np.r_[True, v[1:] <= v[:-1]]
    right = np.r_[v[:-1] <= v[1:], True]
    idx = np.flatnonzero(left & right)
    return [int(i) for i in idx[np.argsort(v[idx])][:n]]


def bracketed_minimum(fun, grid, xatol: float) -> tuple[float, float]:
    """The best point of a monotonic grid, then Brent's bounded search between its neighbours: (x, fun(x))."""
    vals = [fun(g) for g in grid]
    i = int(np.argmin(vals))
    a, b = sorted((grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]))
    if b > a:
        res = minimize_scalar(fun, bounds=(a, b), method="bounded", options={"xatol": xatol})
        if res.fun < vals[i]:
            return float(res.x), float(res.fun)
    return float(grid[i]), float(vals[i])


def prominence(amp: np.ndarray, half_width: int = 50) -> np.ndarray:
    """A spectrum over its running geometric mean (a peak stands out of its neighbourhood, whatever the slope)."""
    log_amp = np.log(np.maximum(amp, 1e-300))
    return np.exp(log_amp - uniform_filter1d(log_amp, size=2 * half_width + 1, mode="nearest"))


def solve_scaled(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Column-scaled least squares (minimum norm below 1e-10 of the largest singular value): (theta, residual)."""
    theta = scaled_lstsq(A, y, rcond=1e-10)
    return theta, y - A @ theta


def column_basis(A: np.ndarray) -> np.ndarray:
    """An orthonormal basis of A's column space (columns scaled to unit norm; singular values below 1e-10 of
    the largest dropped)."""
    d = np.sqrt(np.einsum("ij,ij->j", A, A))
    d[~(d > 0)] = 1.0
    u_, s_, _ = np.linalg.svd(A / d, full_matrices=False)
    return np.ascontiguousarray(u_[:, s_ > 1e-10 * s_[0]])


def own_nonlinear(screen, c: Candidate) -> list[str]:
    return [n for n in c.model.nonlinear_names if n not in screen.base_nl_names]


def open_ended(screen, c: Candidate) -> list[str]:
    """The candidate's parameters at an upper search bound that is a limit within its cause's meaning
    (``Cause.open_ended``: creep's time scale longer than these records show, a straight drift)."""
    return [n for n in own_nonlinear(screen, c) if open_ended_parameter(n)
            and math.log(screen.bounds_of(c.model, n)[1] / float(c.params[n])) < screen.policy.at_bound]


def bound_flags(screen, c: Candidate) -> dict:
    """The held-out score's bound entries: ``at_bound`` and ``open_ended``."""
    return {"at_bound": at_bound(screen, c), "open_ended": open_ended(screen, c)}


def at_bound(screen, c: Candidate) -> list[str]:
    """The candidate's own nonlinear parameters at a search bound (not an ``open_ended`` one)."""
    if not c.kind.bounded:
        return []
    out, near = [], screen.policy.at_bound
    for n in own_nonlinear(screen, c):
        lo, hi = screen.bounds_of(c.model, n)
        v = float(c.params[n])
        owner = cause_of_parameter(n)
        if owner is not None and n in owner.only_upper_bound:  # its lower bound is no effect: only the upper counts
            if v >= hi * (1 - near):
                out.append(n)
        elif is_log(n) and lo > 0:
            if math.log(v / lo) < near or (math.log(hi / v) < near and not open_ended_parameter(n)):
                out.append(n)
        elif v <= lo + near * (hi - lo) or v >= hi - near * (hi - lo):
            out.append(n)
    return out
