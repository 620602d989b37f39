"""Creep: a drift since the record's start, slower than the drive."""

from __future__ import annotations

import math

import numpy as np

from .candidates import Candidate


def fit_creep(screen) -> Candidate:
    model = screen.extension(("creep",))
    lo, hi = screen.bounds_of(model, "creep_time")
    z = screen.line_search(model, "creep_time", np.exp(np.linspace(math.log(lo), math.log(hi), 17)), log=True)
    return screen.candidate("creep", "slow drift since the start", model, z)
