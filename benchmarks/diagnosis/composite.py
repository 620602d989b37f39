"""A cause composed on top of another, one extended model (secondary causes, ``secondary``; a slow part,
``slow_part``).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from hysbench.models.base import HysteresisModel

from .candidates import Candidate, estimates_of, is_log
from .cause import CAUSES, cause_of_parameter, refined

COMPOSITE_GRID = 12  # starts per own parameter of a cause searched on top of another


def composite(screen, primary: Candidate, other: Candidate, max_nfev: int = 10,
              search: bool = False) -> Candidate | None:
    """The primary's extension (itself possibly a composite) plus another cause, refined from both fits
    (separable causes only; else None). With ``search`` the other cause's parameters are also started from a
    grid (``composite_starts``), and the best start is refined only if it removes at least ``min_explained``
    of the primary's sum of squares (else None)."""
    parts = tuple(getattr(primary.model, "components", (primary.cause,)))
    if not all(CAUSES[p].separable for p in (*parts, other.cause)) or other.cause in parts:
        return None
    hyper = {**primary.hyperparameters, **other.hyperparameters}
    model = screen.extension((*parts, other.cause), **hyper)
    start = {n: primary.params.get(n, other.params.get(n)) for n in model.nonlinear_names}
    if search:
        starts = composite_starts(screen, model, start, [n for n in model.nonlinear_names if n not in primary.params])
        starts += other.kind.starts_on_top(primary, starts)
        rss = [screen.evaluate(model, z)[0] for z in starts]
        if min(rss) > (1.0 - screen.policy.min_explained) * primary.rss:
            return None
        start = starts[int(np.argmin(rss))]
    free = [(n, is_log(n)) for n in model.nonlinear_names if refined(n)]
    z = screen.refine(model, start, free, max_nfev=max_nfev) if free else start
    c = screen.candidate(other.cause, f"{primary.label} + {other.label}", model, z, hyper, stage="joint")
    c.estimates = estimates_of(other.cause, c.params, model)
    c.delta_bic = c.bic - primary.bic  # against the primary alone
    c.explained = 1.0 - c.rss / primary.rss
    c.limit = screen.limit_of(other.cause, c.estimates)
    return c


def composite_starts(screen, model: HysteresisModel, start: Mapping[str, float],
                     names: Sequence[str]) -> list[dict]:
    """``start`` and a grid inside the named parameters' search bounds (``Cause.grid_axis``), about
    ``COMPOSITE_GRID`` points in all; a relaxation of several time constants keeps its own start."""
    if not names or (len(names) > 1 and any(cause_of_parameter(n).variants for n in names)):
        return [dict(start)]
    k = max(3, COMPOSITE_GRID // len(names))
    axes = []
    for n in names:
        # inside the bounds (a start at a bound is a bound estimate if nothing moves it)
        axis = cause_of_parameter(n).grid_axis(screen, model, n, k)
        if axis is None:  # nothing to search
            return [dict(start)]
        axes.append(axis)
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(names))
    return [dict(start)] + [{**start, **dict(zip(names, map(float, g)))} for g in grid]
