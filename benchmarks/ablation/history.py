"""The check that periodic history trimming (``hysbench.data.periodic.trim_history``) left a variant's
regressors on the scored windows unchanged."""

from __future__ import annotations


import numpy as np

from hysbench.data.dataset import Dataset
from hysbench.identification import data_scale

from .plan import Variant

def check_trim(full: Dataset, trimmed: Dataset, variant: Variant) -> float:
    """Largest |difference| of the window regressors, full vs trimmed records, relative to
    their largest magnitude, at a (gamma, lambda) away from zero."""
    model = variant.model()
    recs = full.identification or full.records
    scale = data_scale(recs)
    lo, hi = model.bounds(scale)
    names = model.param_names
    nl = np.array([[0.5 * hi[names.index(n)] if n == "gamma" else 0.5 * lo[names.index(n)]
                    for n in model.nonlinear_names]])
    in_range = (float(min(np.min(r.u) for r in full.records)), float(max(np.max(r.u) for r in full.records)))
    worst = 0.0
    for a, b in zip(full.records, trimmed.records):
        if a is b:
            continue
        A = model.windowed_regressors_batch(a.u, a.dt, nl, a.scored, in_range)[0]
        B = model.windowed_regressors_batch(b.u, b.dt, nl, b.scored, in_range)[0]
        worst = max(worst, float(np.max(np.abs(A - B)) / max(1e-300, float(np.max(np.abs(A))))))
    return worst
