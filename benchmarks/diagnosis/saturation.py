"""Saturation: the output clipped at a level, fitted as censored regression (both sides tried)."""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from scipy.optimize import least_squares, minimize_scalar

from .candidates import Candidate, estimates_of


def saturation_rss(screen, side: str, level: float, base_nl: Mapping[str, float],
                   want: bool = False):
    """Censored fit at a clipping level: linear parameters solved on the samples not at the level."""
    sign = 1.0 if side == "upper" else -1.0
    A = np.concatenate(screen.base_columns(base_nl).rows)
    free = sign * screen.y < sign * level - 3.0 * max(screen.noise_sd, 1e-12)
    screen.n_evaluations += 1
    if free.sum() < A.shape[1] + 1:
        return (math.inf, None, None) if want else math.inf
    theta, _ = screen.solve(A[free], screen.y[free])
    pred = A @ theta
    pred = np.minimum(pred, level) if side == "upper" else np.maximum(pred, level)
    r = screen.y - pred
    return (float(r @ r), theta, r) if want else float(r @ r)

def fit_saturation(screen) -> Candidate:
    """Censored fit of a clipping level, both sides; the better side stands for the cause."""
    out = None
    for side in ("upper", "lower"):
        sign = 1.0 if side == "upper" else -1.0
        ys = sign * screen.y
        top, bottom = float(np.max(ys)), float(np.min(ys))
        levels = sign * (top - np.linspace(0.0, 0.3, 31) * (top - bottom))
        vals = [saturation_rss(screen, side, L, screen.base_nl) for L in levels]
        i = int(np.argmin(vals))
        a, b = sorted((levels[max(i - 1, 0)], levels[min(i + 1, len(levels) - 1)]))
        level = float(levels[i])
        if b > a:
            res = minimize_scalar(lambda L: saturation_rss(screen, side, L, screen.base_nl), bounds=(a, b),
                                  method="bounded", options={"xatol": 1e-3 * max(screen.noise_sd, 1e-9)})
            if res.fun < vals[i]:
                level = float(res.x)
        c = _saturation_candidate(screen, side, level, screen.base_nl, "fixed base")
        if c is not None and (out is None or c.bic < out.bic):
            out = c
    return out

def _saturation_candidate(screen, side: str, level: float, base_nl: Mapping[str, float], stage: str):
    rss, theta, _ = saturation_rss(screen, side, level, base_nl, want=True)
    if theta is None:
        return None
    model = screen.extension(("saturation",), saturation_side=side)
    params = {**dict(base_nl), **dict(zip(screen.base_lin, map(float, theta))), "saturation_level": float(level)}
    c = Candidate("saturation", f"clipped from {'above' if side == 'upper' else 'below'}", model, params,
                  model.n_params, rss, screen.n, estimates_of("saturation", params, model),
                  n_effective=screen.n_effective, hyperparameters={"saturation_side": side})
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
