"""Saturation: the output clipped at a level, fitted as censored regression (both sides tried)."""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from scipy.optimize import least_squares, minimize_scalar

from .candidates import Candidate, estimates_of


def unclipped(screen, y: np.ndarray, side: str, level: float) -> np.ndarray:
    """The samples clearly away from a clipping level (by three noise sd) on its side."""
    sign = 1.0 if side == "upper" else -1.0
    return sign * y < sign * level - 3.0 * max(screen.noise_sd, 1e-12)


def censored_fit(screen, A: np.ndarray, y: np.ndarray, side: str, level: float):
    """(rss, theta, residual) of the censored fit at a clipping level: the linear parameters solved on the
    samples not at the level, the prediction clipped there; (inf, None, None) if too few samples are free."""
    free = unclipped(screen, y, side, level)
    screen.n_evaluations += 1
    if free.sum() < A.shape[1] + 1:
        return math.inf, None, None
    theta, _ = screen.solve(A[free], y[free])
    pred = A @ theta
    pred = np.minimum(pred, level) if side == "upper" else np.maximum(pred, level)
    r = y - pred
    return float(r @ r), theta, r


def slope_where_clipped(pred: np.ndarray, y: np.ndarray, side: str, level: float, min_samples: int) -> float:
    """Where the unclipped prediction passes the level: the slope of the output against it (least squares
    with an intercept; 0 for a flat top, 1 for no clip); nan with fewer than ``min_samples`` such samples
    (policy ``min_clipped_samples``)."""
    cut = pred > level if side == "upper" else pred < level
    if cut.sum() < min_samples:
        return math.nan
    p = pred[cut] - pred[cut].mean()
    ss = float(p @ p)
    return float(p @ y[cut]) / ss if ss > 0 else math.nan


def shows_clip(screen, A: np.ndarray, y: np.ndarray, side: str, level: float) -> bool:
    """Whether these rows show a clip at the level: the censored fit's unclipped prediction passes it on enough
    samples and the output there is flat against it (policy ``min_clipped_samples``,
    ``max_clipped_slope``)."""
    _, theta, _ = censored_fit(screen, A, y, side, level)
    if theta is None:
        return False
    slope = slope_where_clipped(A @ theta, y, side, level, screen.policy.min_clipped_samples)
    return math.isfinite(slope) and abs(slope) < screen.policy.max_clipped_slope


def saturation_rss(screen, side: str, level: float, base_nl: Mapping[str, float],
                   want: bool = False):
    """Censored fit at a clipping level on the screen's rows."""
    A = np.concatenate(screen.base_columns(base_nl).rows)
    out = censored_fit(screen, A, screen.y, side, level)
    return out if want else out[0]


def fit_level(screen, A: np.ndarray, y: np.ndarray, side: str) -> float:
    """The clipping level of one side: a grid over the top 30 % of the output range, then Brent."""
    sign = 1.0 if side == "upper" else -1.0
    ys = sign * y
    top, bottom = float(np.max(ys)), float(np.min(ys))
    levels = sign * (top - np.linspace(0.0, 0.3, 31) * (top - bottom))
    vals = [censored_fit(screen, A, y, side, L)[0] for L in levels]
    i = int(np.argmin(vals))
    a, b = sorted((levels[max(i - 1, 0)], levels[min(i + 1, len(levels) - 1)]))
    level = float(levels[i])
    if b > a:
        res = minimize_scalar(lambda L: censored_fit(screen, A, y, side, L)[0], bounds=(a, b),
                              method="bounded", options={"xatol": 1e-3 * max(screen.noise_sd, 1e-9)})
        if res.fun < vals[i]:
            level = float(res.x)
    return level


def fit_saturation(screen) -> Candidate:
    """Censored fit of a clipping level, both sides; the better side stands for the cause."""
    out = None
    A = np.concatenate(screen.base_columns(screen.base_nl).rows)
    for side in ("upper", "lower"):
        c = _saturation_candidate(screen, side, fit_level(screen, A, screen.y, side), screen.base_nl, "fixed base")
        if c is not None and (out is None or c.bic < out.bic):
            out = c
    return out


def _saturation_candidate(screen, side: str, level: float, base_nl: Mapping[str, float], stage: str):
    A = np.concatenate(screen.base_columns(base_nl).rows)
    rss, theta, _ = censored_fit(screen, A, screen.y, side, level)
    if theta is None:
        return None
    model = screen.extension(("saturation",), saturation_side=side)
    params = {**dict(base_nl), **dict(zip(screen.base_lin, map(float, theta))), "saturation_level": float(level)}
    estimates = estimates_of("saturation", params, model)
    slope = slope_where_clipped(A @ theta, screen.y, side, level, screen.policy.min_clipped_samples)
    if math.isfinite(slope):  # else the level cuts no sample
        estimates["slope_where_clipped"] = slope
    c = Candidate("saturation", f"clipped from {'above' if side == 'upper' else 'below'}", model, params,
                  model.n_params, rss, screen.n, estimates, n_effective=screen.n_effective,
                  hyperparameters={"saturation_side": side})
    c.stage = stage
    return screen._finish(c)


def joint_saturation(screen, c: Candidate, max_nfev: int = 15) -> Candidate:
    """Stage 2 for saturation: the base's nonlinear parameters free too, the level held."""
    if not screen.base_nl_names:
        return c
    side = c.hyperparameters["saturation_side"]
    names = list(screen.base_nl_names)
    lo = np.array([screen.bounds_of(screen.base, n)[0] for n in names])
    hi = np.array([screen.bounds_of(screen.base, n)[1] for n in names])
    level = c.params["saturation_level"]

    def fun(x):
        return saturation_rss(screen, side, level, dict(zip(names, x)), want=True)[2]

    x0 = np.clip([c.params[n] for n in names], lo, hi)
    res = least_squares(fun, x0, bounds=(lo, hi), method="trf", diff_step=1e-4, x_scale=hi - lo, max_nfev=max_nfev)
    out = _saturation_candidate(screen, side, level, dict(zip(names, res.x)), "joint")
    return out if out is not None and out.rss < c.rss else c


def columns_of(screen, part: Candidate) -> np.ndarray:
    """A separable candidate's regressors on the screen's rows, at its own nonlinear parameters."""
    return screen.design(part.model, {n: part.params[n] for n in part.model.nonlinear_names})


def clip_on_top(screen, kept: Candidate) -> Candidate | None:
    """A clip of a kept separable part's prediction (a secondary cause): its columns held at the kept fit's
    nonlinear parameters, the level fitted on each side as for the base, the better side kept. It must cut
    the prediction (enough samples, ``candidates.NO_CUT``) and leave the output flat there (``limit_of``)."""
    A = columns_of(screen, kept)
    out = None
    for side in ("upper", "lower"):
        level = fit_level(screen, A, screen.y, side)
        rss, theta, _ = censored_fit(screen, A, screen.y, side, level)
        if theta is None:
            continue
        params = {**kept.params, **dict(zip(kept.model.linear_names, map(float, theta))), "saturation_level": level}
        estimates = {"level": float(level), "side": side}
        slope = slope_where_clipped(A @ theta, screen.y, side, level, screen.policy.min_clipped_samples)
        if math.isfinite(slope):
            estimates["slope_where_clipped"] = slope
        c = Candidate("saturation", f"{kept.label} + clipped from {'above' if side == 'upper' else 'below'}",
                      kept.model, params, kept.k + 1, rss, screen.n, estimates, n_effective=screen.n_effective,
                      hyperparameters={**kept.hyperparameters, "saturation_side": side}, clips=kept)
        c.stage = "joint"
        c.delta_bic = c.bic - kept.bic
        c.explained = 1.0 - c.rss / kept.rss
        c.limit = screen.limit_of("saturation", estimates)
        if out is None or c.rss < out.rss:
            out = c
    return out
