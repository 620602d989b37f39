"""Model discrepancy, and the predictive noise scale set by held-out coverage.

Discrepancy (``discrepancy="relaxation"``, the default). A hysteresis model is always somewhat
wrong, and how wrong depends on the drive: on the virtual DEA plain MRPIM misses the
viscoelastic relaxation, and its error grows from 0.11 mm rms at 0.02 Hz to 0.45 mm at 0.4 Hz.
The posterior adds to the model's output a discrepancy in the input,

    delta(t) = sum_k c_k (L_k u - u)(t),    (L_k u)' = (u - L_k u) / tau_k,   L_k u(0) = u(0),

first-order relaxations of the input at fixed times tau_k, one per decade from 0.1 x the
shortest fitted window to 2 x the longest (0.1, 1, 10, 100 s on the default dataset). It is
linear in c, so c is integrated out exactly with the model's linear parameters (normal prior,
mean 0, sd 2 max|y| / max|u|) and drawn with them; the exact AR(1) noise stays as it was. The
columns are computed once per record on its whole input (a relaxation is not periodic from the
first period, so never on the periodic proxy).

Predictive scale (``calibrate_scale``). The noise model's stationary sd sigma / sqrt(1 - phi^2)
is what the fitted records' residuals say; on a record the fit has not seen the error is usually
larger (and with phi near 1 the stationary sd is poorly determined by short windows, either way).
The predictive noise is therefore multiplied by kappa (0.05-20), chosen so that held-out identification
data are covered at the nominal level: each identification record is left out in turn, the linear
parameters (model and discrepancy) are refitted on the others at the posterior median of
(theta_N, sigma, phi), and the left-out record is predicted (linear-parameter variance plus
kappa^2 times the noise variance). kappa solves: mean held-out 90 % coverage = 90 %, over the
left-out records whose frequency lies inside the range of the others (held out by interpolation,
as validation records are; records at the ends of the frequency range are extrapolation, and are
reported but not used unless no record is interior). A dataset with one identification record
is split into the halves of its window instead. Approximations, stated: theta_N, sigma and phi are
not refitted per fold (the 2 nonlinear MRPIM parameters move little; the 20+ linear ones are
where a fit adapts to its records).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter
from scipy.stats import norm

from ..likelihood import marginalise_linear, whitened_gram

DISCREPANCY_KINDS = ("relaxation", "none")
DISCREPANCY_PRIOR_GAIN = 2.0  # prior sd of c_k: this x max|y| / max|u|
CALIBRATION_LEVEL = 0.9
KAPPA_RANGE = (0.05, 20.0)


def relaxation_times(records) -> np.ndarray:
    """tau_k: one per decade from 0.1 x the shortest fitted window to 2 x the longest (seconds)."""
    durations = [r.n_scored * r.dt for r in records if r.n_scored > 0 and r.dt > 0]
    if not durations:
        return np.zeros(0)
    lo, hi = 0.1 * min(durations), 2.0 * max(durations)
    return np.geomspace(lo, hi, max(2, int(math.floor(math.log10(hi / lo))) + 1))


def discrepancy_names(taus: np.ndarray) -> tuple[str, ...]:
    return tuple(f"delta_tau{t:.3g}s" for t in taus)


def relaxation_columns(u: np.ndarray, dt: float, taus: np.ndarray, window: slice) -> np.ndarray:
    """(n_window, K): L_k u - u on the window, L_k the relaxation at tau_k started at rest at u[0]."""
    u = np.asarray(u, dtype=float)
    out = np.empty((u[window].size, len(taus)))
    for k, tau in enumerate(taus):
        a = math.exp(-dt / tau)
        low = lfilter([1.0 - a], [1.0, -a], u, zi=[a * u[0]])[0]
        out[:, k] = (low - u)[window]
    return out


@dataclass
class Calibration:
    """The predictive noise scale kappa and the held-out folds it came from."""

    scale: float
    level: float
    folds: list[dict] = field(default_factory=list)
    note: str = ""

    def describe(self) -> dict:
        return {"noise_scale": self.scale, "level": self.level, "folds": self.folds, "note": self.note}


def _pieces(post, nl: np.ndarray):
    """Held-out pieces: (label, frequency, design (n, m), y) per identification segment, or the
    two halves of the window when there is only one."""
    out = []
    for s in post.segments:
        X = post.design(s, nl[None])[0]
        out.append((s.file, s.frequency_hz, X, s.y))
    if len(out) == 1:
        label, f, X, y = out[0]
        h = y.size // 2
        out = [(f"{label} (first half)", f, X[:h], y[:h]), (f"{label} (second half)", f, X[h:], y[h:])]
    return out


def calibrate_scale(post, nl: np.ndarray, sigma: float, phi: float, level: float = CALIBRATION_LEVEL) -> Calibration:
    """kappa from leave-one-record-out coverage (module docstring)."""
    pieces = _pieces(post, np.asarray(nl, dtype=float))
    if len(pieces) < 2:
        return Calibration(1.0, level, note="fewer than two held-out pieces: noise scale 1")
    grams = [whitened_gram(X.T[None], y, np.array([phi]))[0] for _, _, X, y in pieces]
    total = np.sum(grams, axis=0)
    noise_var = sigma**2 / (1.0 - phi**2)
    z = norm.ppf(0.5 + level / 2)
    held = []
    for i, (label, f, X, y) in enumerate(pieces):
        G = total - grams[i]
        n_rows = sum(p[3].size for j, p in enumerate(pieces) if j != i)
        marg = marginalise_linear(G[None], np.array([sigma]), n_rows, np.zeros(1), post.priors.linear_mean,
                                  post.priors.linear_precision)
        if not marg.ok[0]:
            continue
        cov = marg.covariance(0)
        err = y - X @ marg.mean[0]
        param_var = np.einsum("ij,jk,ik->i", X, cov, X)
        others = [p[1] for j, p in enumerate(pieces) if j != i and p[1]]
        interior = bool(f and others and min(others) < f < max(others))
        held.append({"label": label, "frequency_hz": f, "interior": interior, "err": err, "param_var": param_var,
                     "rms_error": float(np.sqrt(np.mean(err**2)))})
    if not held:
        return Calibration(1.0, level, note="no fold could be refitted: noise scale 1")
    any_interior = any(h["interior"] for h in held)
    for h in held:
        h["used"] = h["interior"] or not any_interior
    used = [h for h in held if h["used"]]

    def coverage(h, kappa):
        return float(np.mean(np.abs(h["err"]) <= z * np.sqrt(h["param_var"] + kappa**2 * noise_var)))

    def mean_cov(kappa):
        return float(np.mean([coverage(h, kappa) for h in used]))

    lo, hi = KAPPA_RANGE
    if mean_cov(lo) >= level:
        kappa = lo
    elif mean_cov(hi) < level:
        kappa = hi
    else:
        for _ in range(60):  # bisection in log kappa; coverage grows with kappa
            mid = math.sqrt(lo * hi)
            lo, hi = (mid, hi) if mean_cov(mid) < level else (lo, mid)
        kappa = hi
    folds = [{"held_out": h["label"], "frequency_hz": h["frequency_hz"], "used": h["used"],
              "interior": h["interior"], "rms_error": h["rms_error"],
              f"coverage_{int(round(level * 100))}_unscaled": coverage(h, 1.0),
              f"coverage_{int(round(level * 100))}_scaled": coverage(h, kappa)} for h in held]
    note = ("mean held-out coverage over interior records" if any_interior
            else "mean held-out coverage over every held-out piece (none is interior)")
    return Calibration(float(kappa), level, folds, note)
