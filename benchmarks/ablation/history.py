"""Periodic history trimming: drop whole periods before the scored window (checked)."""

from __future__ import annotations


import numpy as np

from hysbench.data.dataset import Dataset, Record
from hysbench.identification import data_scale

from .plan import AblationError, TRIM_CHECK_RTOL, Variant

def trim_history(dataset: Dataset, periods: int = 1, rtol: float = TRIM_CHECK_RTOL) -> tuple[Dataset, list[dict]]:
    """The dataset with whole input periods removed before each scored window
    (keeping ``periods`` >= 1 of them) and the samples after it, where the
    record's input is periodic from its first sample; see the module docstring."""
    if periods < 1:
        raise AblationError("trim_history needs at least one period of history before the window")
    records, info = [], []
    for r in dataset.records:
        kept = {"file": r.file, "samples": int(r.t.size), "first_sample": 0, "trimmed": False, "reason": ""}
        k0, reason = _trim_start(r, periods, rtol)
        if k0 > 0 or r.stop < r.t.size:
            s = slice(k0, r.stop)
            records.append(Record(file=r.file, t=r.t[s].copy(), u=r.u[s].copy(), y=r.y[s].copy(), role=r.role,
                                  frequency_hz=r.frequency_hz, weight=r.weight, window=r.window,
                                  start=r.start - k0, stop=r.stop - k0))
            kept.update(first_sample=int(k0), samples_kept=int(r.stop - k0), trimmed=True)
        else:
            records.append(r)
            kept["samples_kept"] = int(r.t.size)
        kept["reason"] = reason
        info.append(kept)
    trimmed = Dataset(name=dataset.name, records=records, description=dataset.description,
                      time_column=dataset.time_column, input_column=dataset.input_column,
                      output_column=dataset.output_column, input_unit=dataset.input_unit,
                      output_unit=dataset.output_unit, path=dataset.path)
    return trimmed, info


def _trim_start(r: Record, periods: int, rtol: float) -> tuple[int, str]:
    """First kept sample (a whole number of periods from sample 0) and why."""
    if not r.frequency_hz or r.t.size < 2:
        return 0, "no frequency: kept whole"
    p_float = 1.0 / (r.frequency_hz * r.dt)
    period = int(round(p_float))
    if period < 2 or abs(p_float - period) > 1e-6 * p_float:
        return 0, "period is not a whole number of samples: kept whole"
    k0 = ((r.start - periods * period) // period) * period
    if k0 <= 0:
        return 0, f"fewer than {periods + 1} periods before the window: nothing to trim"
    u = r.u[:r.stop]
    tol = rtol * max(1.0, float(np.max(np.abs(u))))
    if float(np.max(np.abs(u[period:] - u[:-period]))) > tol:
        return 0, "input is not periodic from the first sample: kept whole"
    return k0, f"input periodic ({period} samples); {k0 // period} period(s) before the window dropped"


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
