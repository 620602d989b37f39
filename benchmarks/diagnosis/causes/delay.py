"""Delay: the actuator receives the input late (searched to first order, then exactly)."""

from __future__ import annotations

import math
from typing import Callable

import numpy as np
from scipy.optimize import minimize_scalar

from ..candidates import Candidate, local_minima
from ..cause import Cause, register

PROFILE_POINTS = 16
PROFILE_NFEV = 4
PROFILE_XTOL = 0.01  # Brent's tolerance on the profile, relative to its bracket
SCAN_POINTS = 24  # the profile between the best grid point's neighbours: every half sample, at most this many
EXACT_SCAN_POINTS = 160  # short records: the exact profile (base held) every sample up to the bound, at most this many


def _delayed_null(screen, z):
    def column(m):
        y0, rows = screen._null_prediction[m], screen.parts[m].rows
        pos = rows - z["delay"] / screen.parts[m].record.dt
        return np.interp(pos, np.arange(y0.size), y0, left=screen._null_rest[m]) - y0[rows]
    return screen.first_order(column)


def scan_minimum(rss: Callable[[float], float], a: float, b: float, dt: float) -> float:
    """The minimum of a delay's profile in [a, b]: scanned every half sample (at most ``SCAN_POINTS``), then Brent
    around the scan's best. The profile is rough at the scale of a sample: a gradient step is no use."""
    step = max(dt / 2, (b - a) / SCAN_POINTS)
    pts = np.r_[a, np.arange(a + step, b, step), b]
    vals = [rss(float(d)) for d in pts]
    centre = float(pts[int(np.argmin(vals))])
    lo, up = max(centre - step, a), min(centre + step, b)
    if up > lo:
        r = minimize_scalar(rss, bounds=(lo, up), method="bounded", options={"xatol": PROFILE_XTOL * (up - lo)})
        if r.fun < min(vals):
            return float(r.x)
    return centre


def fit_delay(screen) -> Candidate:
    """Searched to first order (the null's prediction delayed) every two samples or so; if promising, from its
    best points and one sample exactly. On short records (``Screen.small``) the exact profile, the base's
    nonlinear parameters refitted at each delay (rate-dependent terms take up part of one), over a geometric
    grid and the best points of both scans, then ``scan_minimum`` between the best point's neighbours."""
    model = screen.extension(("delay",))
    dt = min(p.record.dt for p in screen.parts)
    hi = screen.bounds_of(model, "delay")[1]
    grid = np.linspace(0.0, hi, int(min(max(hi / (2 * dt), 10), 400)) + 1)
    vals = np.array([_delayed_null(screen, {**screen.base_nl, "delay": float(d)})[0] for d in grid])
    if not (screen.promising(float(vals.min())) or screen.small):  # not even to first order: one exact evaluation
        return screen.candidate("delay", "pure delay", model, {**screen.base_nl, "delay": float(grid[np.argmin(vals)])})
    starts = [float(grid[i]) for i in local_minima(vals, 2)] + [min(dt, hi)]
    if not screen.small:
        best, best_rss = None, math.inf
        for d0 in starts:
            z = screen.line_search(model, "delay", [max(d0 - 2 * dt, 0.0), d0, min(d0 + 2 * dt, hi)])
            rss = screen.evaluate(model, z)[0]
            if rss < best_rss:
                best, best_rss = z, rss
        return screen.candidate("delay", "pure delay", model, best)
    free = [(n, False) for n in screen.base_nl_names]
    profile: dict[float, tuple[float, dict]] = {}

    def profile_rss(d: float) -> float:
        d = float(d)
        if d not in profile:
            z = {**screen.base_nl, "delay": d}
            z = screen.refine(model, z, free, max_nfev=PROFILE_NFEV) if free else z
            profile[d] = (screen.evaluate(model, z)[0], z)
        return profile[d][0]

    # the exact profile (the base held) every sample too: a misfit with sharp features, e.g. the corners of a
    # triangle drive, gives a valley about a sample wide, between the grid's steps, where the first-order one is flat
    step = max(dt, hi / EXACT_SCAN_POINTS)
    scan = np.arange(0.0, hi + step / 2, step)
    exact = np.array([screen.evaluate(model, {**screen.base_nl, "delay": float(d)})[0] for d in scan])
    starts += [float(scan[i]) for i in local_minima(exact, 2)]
    grid_d = np.unique(np.r_[np.geomspace(min(dt, hi), hi, PROFILE_POINTS), starts])
    j = int(np.argmin([profile_rss(d) for d in grid_d]))
    scan_minimum(profile_rss, (float(grid_d[j - 1]) if j else 0.0), float(grid_d[min(j + 1, grid_d.size - 1)]), dt)
    return screen.candidate("delay", "pure delay", model, min(profile.values(), key=lambda v: v[0])[1], stage="joint")


@register
class Delay(Cause):
    name = "delay"
    units = {"delay_s": "s"}
    reported_as = {"delay": "delay_s"}
    parameters = ("delay",)
    only_upper_bound = ("delay",)  # a delay at zero is no delay
    transforms = True
    late_input = True
    reshapes = True

    def library_terms(self, screen, y_hat_rows: np.ndarray):  # a short delay to first order
        return ["d/dt y_model"], lambda r, y_hat, t: [np.gradient(y_hat, r.dt)], [None]

    def fit(self, screen, library: dict, max_order: int) -> list[Candidate]:
        return [fit_delay(screen)]

    def limit(self, screen, estimates) -> str:
        if estimates["delay_s"] < (dt := max(p.record.dt for p in screen.parts)):
            return (f"shorter than one sample ({1e3 * dt:.3g} ms): an input late by less than a sample is the input "
                    "plus a first difference of it (a rate term), not a resolved delay")
        return ""

    def refit_alone(self, screen, model, start: dict, training_rss: Callable[[dict], float]) -> dict:
        """``scan_minimum`` between the estimate's neighbours on ``fit_delay``'s geometric grid, the rest held."""
        dt = min(p.record.dt for p in screen.parts)
        hi = screen.bounds_of(model, "delay")[1]
        ratio = (hi / min(dt, hi)) ** (1.0 / (PROFILE_POINTS - 1))
        d0 = float(start["delay"])
        return {**start, "delay": scan_minimum(lambda v: training_rss({**start, "delay": v}), d0 / ratio,
                                               min(d0 * ratio, hi), dt)}

    def grid_axis(self, screen, model, parameter: str, k: int) -> np.ndarray | None:
        """Geometric from one sample (a start at zero is no delay) to its bound."""
        hi = screen.bounds_of(model, parameter)[1]
        lo = min(p.record.dt for p in screen.parts)
        return np.geomspace(lo, hi, k + 2)[1:-1] if hi > lo else None
