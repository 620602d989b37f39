"""Saturation: the output clipped at a level, fitted as censored regression (both sides tried)."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import least_squares

from ..candidates import NO_CUT, Candidate, bracketed_minimum
from ..cause import OUTPUT_UNIT, Cause, register

SIDES = {"upper": "clipped from above", "lower": "clipped from below"}  # a clip's sides and their labels


def clipped(y: np.ndarray, side: str, level: float) -> np.ndarray:
    return np.minimum(y, level) if side == "upper" else np.maximum(y, level)


def unclipped(screen, y: np.ndarray, side: str, level: float) -> np.ndarray:
    """The samples clearly away from a clipping level (by three noise sd) on its side."""
    sign = 1.0 if side == "upper" else -1.0
    return sign * y < sign * level - 3.0 * max(screen.noise_sd, 1e-12)


def censored_fit(screen, A: np.ndarray, y: np.ndarray, side: str, level: float):
    """(rss, theta, residual): the linear parameters solved on the samples not at the level, the prediction
    clipped there; (inf, None, None) if too few samples are free."""
    free = unclipped(screen, y, side, level)
    if free.sum() < A.shape[1] + 1:
        return math.inf, None, None
    theta, _ = screen.solve(A[free], y[free])
    r = y - clipped(A @ theta, side, level)
    return float(r @ r), theta, r


def slope_where_clipped(pred: np.ndarray, y: np.ndarray, side: str, level: float, min_samples: int) -> float:
    """Where the unclipped prediction passes the level, the slope of the output against it (0 for a flat top, 1
    for no clip); nan with fewer than ``min_samples`` such samples."""
    cut = pred > level if side == "upper" else pred < level
    if cut.sum() < min_samples:
        return math.nan
    p = pred[cut] - pred[cut].mean()
    ss = float(p @ p)
    return float(p @ y[cut]) / ss if ss > 0 else math.nan


def shows_clip(screen, A: np.ndarray, y: np.ndarray, side: str, level: float) -> bool:
    """Whether the censored fit's prediction passes the level on enough samples and the output there is flat
    against it (within ``max_clipped_slope``)."""
    _, theta, _ = censored_fit(screen, A, y, side, level)
    if theta is None:
        return False
    slope = slope_where_clipped(A @ theta, y, side, level, screen.policy.min_clipped_samples)
    return math.isfinite(slope) and abs(slope) < screen.policy.max_clipped_slope


def fit_level(screen, A: np.ndarray, y: np.ndarray, side: str) -> float:
    """The clipping level of one side: a grid over the top 30 % of the output range, then Brent."""
    sign = 1.0 if side == "upper" else -1.0
    top, bottom = float(np.max(sign * y)), float(np.min(sign * y))
    levels = sign * (top - np.linspace(0.0, 0.3, 31) * (top - bottom))
    return bracketed_minimum(lambda L: censored_fit(screen, A, y, side, L)[0], levels,
                             1e-3 * max(screen.noise_sd, 1e-9))[0]


def _estimates(screen, A: np.ndarray, theta: np.ndarray, side: str, level: float) -> dict:
    """A clip's estimates with the slope where its level cuts (``slope_where_clipped``; none if it cuts nothing)."""
    slope = slope_where_clipped(A @ theta, screen.y, side, level, screen.policy.min_clipped_samples)
    return {"level": float(level), "side": side, **({"slope_where_clipped": slope} if math.isfinite(slope) else {})}


def _of_base(screen, side: str, level: float, base_nl, stage: str) -> Candidate | None:
    A = np.concatenate(screen.base_columns(base_nl).rows)
    rss, theta, _ = censored_fit(screen, A, screen.y, side, level)
    if theta is None:
        return None
    model = screen.extension(("saturation",), saturation_side=side)
    params = {**dict(base_nl), **dict(zip(screen.base_lin, map(float, theta))), "saturation_level": float(level)}
    return screen._finish(Candidate("saturation", SIDES[side], model, params, model.n_params, rss, screen.n,
                                    _estimates(screen, A, theta, side, level), n_effective=screen.n_effective,
                                    hyperparameters={"saturation_side": side}, stage=stage))


def columns_of(screen, part: Candidate) -> np.ndarray:
    """A separable candidate's regressors on the screen's rows, at its own nonlinear parameters."""
    return screen.design(part.model, {n: part.params[n] for n in part.model.nonlinear_names})


@register
class Saturation(Cause):
    name = "saturation"
    units = {"level": OUTPUT_UNIT, "side": ""}
    reported_as = {"saturation_level": "level"}
    parameters = ("saturation_level",)
    relative_to_range = ("saturation_level",)  # a level has no natural zero
    bounded = False  # its level is searched over the output's range, not between bounds
    separable = False
    carries_others = False  # nothing composes on top of a clip; a disturbance still adds

    def library_terms(self, screen, y_hat_rows: np.ndarray):  # hinges of the model's output at its extremes
        q_hi, q_lo = np.quantile(y_hat_rows, [0.90, 0.97]), np.quantile(y_hat_rows, [0.03, 0.10])
        return ([f"max(y_model-{L:.3g},0)" for L in q_hi] + [f"max({L:.3g}-y_model,0)" for L in q_lo],
                lambda r, y_hat, t: ([np.maximum(y_hat - L, 0.0) for L in q_hi]
                                     + [np.maximum(L - y_hat, 0.0) for L in q_lo]),
                [None] * 4)

    def fit(self, screen, library: dict, max_order: int) -> list[Candidate]:
        """A censored fit of a clipping level on each side; the better side stands for the cause."""
        A = np.concatenate(screen.base_columns(screen.base_nl).rows)
        fits = [_of_base(screen, side, fit_level(screen, A, screen.y, side), screen.base_nl, "fixed base")
                for side in SIDES]
        fits = [c for c in fits if c is not None]
        return [min(fits, key=lambda c: c.bic)] if fits else []

    def joint(self, screen, c: Candidate, max_nfev: int) -> Candidate:
        """The base's nonlinear parameters free too, the level held."""
        if not screen.base_nl_names:
            return c
        side, level = c.hyperparameters["saturation_side"], c.params["saturation_level"]
        names = list(screen.base_nl_names)
        lo = np.array([screen.bounds_of(screen.base, n)[0] for n in names])
        hi = np.array([screen.bounds_of(screen.base, n)[1] for n in names])

        def fun(x):
            A = np.concatenate(screen.base_columns(dict(zip(names, x))).rows)
            return censored_fit(screen, A, screen.y, side, level)[2]

        x0 = np.clip([c.params[n] for n in names], lo, hi)
        res = least_squares(fun, x0, bounds=(lo, hi), method="trf", diff_step=1e-4, x_scale=hi - lo,
                            max_nfev=max_nfev)
        out = _of_base(screen, side, level, dict(zip(names, res.x)), "joint")
        return out if out is not None and out.rss < c.rss else c

    def estimates(self, params, model) -> dict:
        return {"level": float(params["saturation_level"]), "side": getattr(model, "saturation_side", "upper")}

    def limit(self, screen, estimates) -> str:
        if "slope_where_clipped" not in estimates:  # the level cuts (almost) nothing
            return NO_CUT
        if abs(slope := estimates["slope_where_clipped"]) >= screen.policy.max_clipped_slope:
            return (f"where it would clip, the output still {'rises with' if slope > 0 else 'moves against'} the "
                    f"model (slope {slope:.2f}; a clip leaves it flat): not a clip")
        return ""

    def on_top(self, screen, kept: Candidate, own: Candidate, search: bool) -> Candidate | None:
        """A clip of a kept part's prediction, its columns at the part's nonlinear parameters, the better side."""
        A = columns_of(screen, kept)
        fits = []
        for side, label in SIDES.items():
            level = fit_level(screen, A, screen.y, side)
            rss, theta, _ = censored_fit(screen, A, screen.y, side, level)
            if theta is None:
                continue
            params = {**kept.params, **dict(zip(kept.model.linear_names, map(float, theta))), "saturation_level": level}
            estimates = _estimates(screen, A, theta, side, level)
            c = Candidate("saturation", f"{kept.label} + {label}", kept.model, params, kept.k + 1, rss, screen.n,
                          estimates, n_effective=screen.n_effective,
                          hyperparameters={**kept.hyperparameters, "saturation_side": side}, clips=kept)
            c.delta_bic = c.bic - kept.bic
            c.explained = 1.0 - c.rss / kept.rss
            c.limit = screen.limit_of(c.cause, estimates)
            fits.append(c)
        return min(fits, key=lambda c: c.rss) if fits else None

    def clip(self, c: Candidate, y: np.ndarray) -> np.ndarray:
        return clipped(y, c.hyperparameters["saturation_side"], c.params["saturation_level"])

    def heldout_errors(self, screen, folds, c: Candidate, refit: bool, train_residuals: list | None):
        """The linear parameters solved on the other records' free samples, with ``refit`` the level too; a fold
        whose records show no clip (``shows_clip``) predicts unclipped: a level just under their peaks would cut
        a record that goes higher."""
        side, level = c.hyperparameters["saturation_side"], c.params["saturation_level"]
        A = columns_of(screen, c.clips) if c.clips is not None else np.concatenate(
            screen.base_columns({k: c.params[k] for k in screen.base_nl_names}).rows)
        e = np.zeros(screen.n)
        fold_est = []
        for m in range(folds.n):
            test = folds.test(m)
            if refit:
                level = fit_level(screen, A[~test], screen.y[~test], side)
                fold_est.append({"saturation_level": level})
                if not shows_clip(screen, A[~test], screen.y[~test], side, level):
                    level = math.inf if side == "upper" else -math.inf
            train = ~test & unclipped(screen, screen.y, side, level)
            theta, _ = screen.solve(A[train], screen.y[train])
            e[test] = screen.y[test] - clipped(A[test] @ theta, side, level)
            e[folds.tail(m)] = 0.0
            if train_residuals is not None:
                train_residuals.append(screen.y[~test] - clipped(A[~test] @ theta, side, level))
        return e, fold_est
