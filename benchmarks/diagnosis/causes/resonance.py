"""Resonance: a second-order mode (searched to first order on a grid, then exactly)."""

from __future__ import annotations

import math

import numpy as np

from hysbench.models.extended import RESONANCE_HZ_BOUNDS
from hysbench.models.filter_kernels import lowpass2_rows, second_order_foh

from ..candidates import Candidate
from ..cause import Cause, register


def _resonant_null(screen, z):
    def column(m):
        y0 = screen._null_prediction[m] - screen._null_offset
        rows = screen.parts[m].rows
        phi, g0, g1 = second_order_foh(z["natural_frequency"], z["damping_ratio"], screen.parts[m].record.dt)
        return lowpass2_rows(np.ascontiguousarray(y0[None, :]), phi, g0, g1)[0][rows] - y0[rows]
    return screen.first_order(column)


def lag_shared(z: dict) -> dict:
    """A mode's start on top of a kept delay, the delay shortened by the mode's low-frequency lag
    (2 zeta / omega_n = zeta / (pi f_n)): a delay fitted first has taken up that lag, so with it held a mode
    at its true values adds the lag twice and predicts worse than none."""
    lag = z["damping_ratio"] / (math.pi * z["natural_frequency"])
    return {**z, "delay": max(float(z["delay"]) - lag, 0.0)}


@register
class Resonance(Cause):
    name = "resonance"
    units = {"natural_frequency_hz": "Hz", "damping_ratio": ""}
    reported_as = {"natural_frequency": "natural_frequency_hz", "damping_ratio": "damping_ratio"}
    parameters = ("natural_frequency", "damping_ratio")
    log_scale = ("natural_frequency", "damping_ratio")
    identifying = ("natural_frequency",)  # its damping is its shape
    transforms = True
    reshapes = True

    def library_terms(self, screen, y_hat_rows: np.ndarray):  # a mode's inertia to first order
        return ["d2/dt2 y_model"], lambda r, y_hat, t: [np.gradient(np.gradient(y_hat, r.dt), r.dt)], [None]

    def fit(self, screen, library: dict, max_order: int) -> list[Candidate]:
        """Searched to first order (the null's prediction through the mode) on a grid and refined; if promising, the
        best of it, a fast well-damped mode (and on short records the grid's two best points) refined exactly."""
        model = screen.extension(("resonance",))
        T = screen.drive_time
        dt = min(p.record.dt for p in screen.parts)
        f_lo = screen.bounds_of(model, "natural_frequency")[0]
        f_hi = min(RESONANCE_HZ_BOUNDS[1] / T, 0.1 / dt)
        # 13 points above the drive's frequencies; as dense below them, down to a broadband drive's band
        f_drive = RESONANCE_HZ_BOUNDS[0] / T
        above = math.log(f_hi / (1.2 * f_drive))
        n_grid = 13 + (math.ceil(12 * math.log(f_drive / f_lo) / above) if f_lo < f_drive and above > 0 else 0)
        fs = np.exp(np.linspace(math.log(f_lo * 1.2), math.log(f_hi), n_grid))
        pts = [{**screen.base_nl, "natural_frequency": float(f), "damping_ratio": zeta} for f in fs
               for zeta in (0.07, 0.25, 0.8)]
        vals = np.array([_resonant_null(screen, z)[0] for z in pts])
        z = screen.refine(model, pts[int(np.argmin(vals))], [("natural_frequency", True), ("damping_ratio", True)],
                          max_nfev=12, residual=lambda q: _resonant_null(screen, q)[2])
        z = {**z, "damping_ratio": min(z["damping_ratio"], screen.policy.max_damping)}
        if not (screen.promising(_resonant_null(screen, z)[0]) or screen.small):  # one exact evaluation
            return [screen.candidate("resonance", "second-order mode", model, z)]
        starts = [z, {**screen.base_nl, "natural_frequency": float(fs[-1]), "damping_ratio": 0.7}]
        if screen.small:  # cheap: the best points of an exact coarse grid too
            exact = [screen.evaluate(model, q)[0] for q in pts]
            starts += [pts[i] for i in np.argsort(exact)[:2]]
        starts = [{**q, "damping_ratio": min(q["damping_ratio"], screen.policy.max_damping)} for q in starts]
        z = min(starts, key=lambda q: screen.evaluate(model, q)[0])
        z = screen.refine(model, z, [("natural_frequency", True), ("damping_ratio", True)], max_nfev=10)
        return [screen.candidate("resonance", "second-order mode", model, z)]

    def bounds(self, screen, parameter: str, lo: float, hi: float) -> tuple[float, float]:
        if parameter == "damping_ratio":  # a mode: underdamped
            return lo, min(hi, screen.policy.max_damping)
        return min(lo, screen.mode_floor), min(hi, screen.nyquist)  # down to a broadband drive's band

    def limit(self, screen, estimates) -> str:
        pol = screen.policy
        if estimates["damping_ratio"] >= pol.damping_limit_share * pol.max_damping:
            return f"damping ratio at the limit {pol.max_damping:g}: no mode"
        return ""

    def starts_on_top(self, primary: Candidate, starts: list[dict]) -> list[dict]:
        return [lag_shared(q) for q in starts[1:]] if "delay" in primary.params else []
