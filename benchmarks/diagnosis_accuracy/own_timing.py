"""A base's own lead on the base model: the reference a planted delay composes with (benchmark-only).

On a plant that is not the base model (a real recording), the base model
alone may fit the unplanted records best with their output delayed by some
s* > 0: the plant leads what the base model can represent. A planted delay d
then shows, beyond the base model, as about d - s*, and the diagnosis (which
reports the delay beyond the base model) can at most find that. Measured on
the unplanted records (every planted effect's signal taken off) by delaying
their output (``planted.fractional_delay``, the generator's own shift, not
the delay extension) and refitting the base model's nonlinear parameters on
the screen's rows: a grid over [0, ``MAX_LEAD_S``], then bounded Brent
around the best point (a lead of ``MAX_LEAD_S`` or more comes back as
``MAX_LEAD_S``). Only leads are measured: an output advanced in time
needs samples after a record's end. The Table 2 MRPIM base is the plant,
so its lead is zero by construction and not measured.
"""

from __future__ import annotations

import copy
from typing import Mapping

import numpy as np
from scipy.optimize import minimize_scalar

from .planted import fractional_delay

MAX_LEAD_S = 0.030  # the planted delays' upper end
GRID_STEP_S = 0.0025
XATOL_S = 2e-4


def base_rss_with_output_delayed(screen, unplanted: Mapping[str, np.ndarray], s: float) -> float:
    """The base model's sum of squares on the screen's rows, its nonlinear parameters refitted, with each
    identification record's unplanted output delayed by ``s`` seconds."""
    shifted = copy.copy(screen)
    ys = []
    for p in screen.parts:
        y = np.asarray(unplanted[p.record.file], dtype=float)
        ys.append((fractional_delay(y, p.record.dt, s, rest=float(y[0])) if s > 0 else y)[p.rows])
    shifted.y = np.concatenate(ys)
    free = [(n, False) for n in screen.base_nl_names]
    z = shifted.refine(screen.base, dict(screen.base_nl), free) if free else dict(screen.base_nl)
    return float(shifted.evaluate(screen.base, z)[0])


def own_lead(screen, planted: Mapping[str, Mapping[str, np.ndarray]]) -> float | None:
    """s* >= 0 (seconds): the output delay at which the base model alone fits the unplanted identification
    records best (``planted``: per planted effect, what it added per record, ``planted_case``'s
    ``truth["signals"]``; every effect is taken off); None if the screen's records are not the planted ones
    sample for sample."""
    unplanted = {}
    for p in screen.parts:
        y = p.record.y.copy()
        for per_record in planted.values():
            added = per_record.get(p.record.file)
            if added is None or np.shape(added) != y.shape:
                return None
            y -= np.asarray(added)
        unplanted[p.record.file] = y
    grid = np.arange(0.0, MAX_LEAD_S + GRID_STEP_S / 2, GRID_STEP_S)
    rss = [base_rss_with_output_delayed(screen, unplanted, s) for s in grid]
    k = int(np.argmin(rss))
    lo, hi = grid[max(k - 1, 0)], grid[min(k + 1, grid.size - 1)]
    best = minimize_scalar(lambda s: base_rss_with_output_delayed(screen, unplanted, s), bounds=(lo, hi),
                           method="bounded", options={"xatol": XATOL_S})
    return float(best.x) if best.fun < rss[k] else float(grid[k])


def needs_lead(row: Mapping) -> bool:
    """A case whose delay estimate is judged on a base other than the Table 2 MRPIM: a delay planted and
    found (named or under "also")."""
    return ("delay" in row["kinds"] and row["base"] != "mrpim"
            and (row["verdict"] == "delay" or "delay" in row["also"]))

