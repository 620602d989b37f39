"""Creep: a drift since the record's start, slower than the drive."""

from __future__ import annotations

import math

import numpy as np

from hysbench.models.extended import CREEP_TIME_BOUNDS

from ..candidates import Candidate
from ..cause import OUTPUT_UNIT, Cause, register


@register
class Creep(Cause):
    name = "creep"
    units = {"size": OUTPUT_UNIT, "time_scale_s": "s"}
    reported_as = {"creep_size": "size", "creep_time": "time_scale_s"}
    parameters = ("creep_time",)
    log_scale = ("creep_time",)
    open_ended = ("creep_time",)  # longer than the records show: a straight drift since the start
    time_scale = "creep_time"
    shown_at_rest = True

    def library_terms(self, screen, y_hat_rows: np.ndarray):
        longest = CREEP_TIME_BOUNDS[1] * screen.drive_time / 10
        creeps = np.exp(np.linspace(math.log(screen.creep_min), math.log(longest), 5))
        return ([f"1-exp(-t/{c:.3g}s)" for c in creeps], lambda r, y_hat, t: [-np.expm1(-t / c) for c in creeps],
                [None] * len(creeps))

    def fit(self, screen, library: dict, max_order: int) -> list[Candidate]:
        model = screen.extension(("creep",))
        lo, hi = screen.bounds_of(model, "creep_time")
        z = screen.line_search(model, "creep_time", np.exp(np.linspace(math.log(lo), math.log(hi), 17)), log=True)
        return [screen.candidate("creep", "slow drift since the start", model, z)]

    def bounds(self, screen, parameter: str, lo: float, hi: float) -> tuple[float, float]:
        return max(lo, screen.creep_min), hi

    def limit(self, screen, estimates) -> str:
        pol = screen.policy
        if estimates["time_scale_s"] <= pol.creep_limit_margin * screen.creep_min:
            return f"time scale at the limit {screen.creep_min:.3g} s ({pol.creep_periods:g} drive periods): not slow"
        return ""
