"""The periodic-history shortcut: a record whose input is periodic from its first sample needs
only a little of its history to reproduce its scored window.

Why it holds (for models whose state is driven by the input alone, the P-I family). For an input
periodic with P samples from sample 0, a play operator's state is periodic from sample P + 1 on:
its map over one period is a composition of clamps max(a, min(b, w)), which is again a clamp, and
applying a clamp twice changes nothing. So whole periods before the scored window can be dropped
without changing the window's outputs. Rate-dependent states (relaxation, creep) do NOT have this
property; callers must check the shortcut on the model at hand (the posterior does, the ablation
checks its fits on the full records).

Two shapes of the same shortcut:

* ``trim_history(dataset, periods)``: a Dataset whose records start a whole number of periods
  before the window (keeping ``periods`` >= 1 of them) and end at the window's end; the ablation's
  contract (``TrimInfo`` per record says what was done and why).
* ``periodic_proxy(record)``: the shortest input with the same window outputs,
  u[:2P-2] ++ u[start-2:stop], and where the window sits in it; the posterior's contract (the two
  samples before the window are the record's own, so derivative columns are bit-identical).
"""

from __future__ import annotations

import numpy as np

from .dataset import Dataset, DatasetError, Record

PERIODIC_RTOL = 1e-9  # u[k + P] == u[k] within this times max(1, max |u|)


def input_period(record: Record, rtol: float = PERIODIC_RTOL) -> tuple[int | None, str]:
    """(P, reason) if the record's input up to its window's end is periodic with P samples from
    sample 0, else (None, why not)."""
    f = record.frequency_hz
    if not f or record.t.size < 2 or not record.dt > 0:
        return None, "no frequency: kept whole"
    p_float = 1.0 / (f * record.dt)
    period = int(round(p_float))
    if period < 2 or abs(p_float - period) > 1e-6 * p_float:
        return None, "period is not a whole number of samples: kept whole"
    stop = record.stop
    if stop <= period:
        return None, "shorter than two periods: kept whole"
    u = record.u[:stop]
    tol = rtol * max(1.0, float(np.max(np.abs(u))))
    if float(np.max(np.abs(u[period:] - u[:-period]))) > tol:
        return None, "input is not periodic from the first sample: kept whole"
    return period, f"input periodic ({period} samples)"


def trimmed_start(record: Record, periods: int = 1, rtol: float = PERIODIC_RTOL) -> tuple[int, str]:
    """First kept sample (a whole number of periods from sample 0, ``periods`` periods or more
    before the window) and why."""
    period, reason = input_period(record, rtol)
    if period is None:
        return 0, reason
    k0 = ((record.start - periods * period) // period) * period
    if k0 <= 0:
        return 0, f"fewer than {periods + 1} periods before the window: nothing to trim"
    return k0, f"{reason}; {k0 // period} period(s) before the window dropped"


def trim_history(dataset: Dataset, periods: int = 1, rtol: float = PERIODIC_RTOL) -> tuple[Dataset, list[dict]]:
    """The dataset with whole input periods removed before each scored window (keeping
    ``periods`` >= 1 of them) and the samples after it, where the record's input is periodic
    from its first sample; one info dict per record (file, samples, first_sample, samples_kept,
    trimmed, reason)."""
    if periods < 1:
        raise DatasetError("trim_history needs at least one period of history before the window")
    records, info = [], []
    for r in dataset.records:
        kept = {"file": r.file, "samples": int(r.t.size), "first_sample": 0, "trimmed": False, "reason": ""}
        k0, reason = trimmed_start(r, periods, rtol)
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


def periodic_proxy(record: Record, rtol: float = PERIODIC_RTOL) -> tuple[np.ndarray, slice] | None:
    """A short input with the same outputs on the record's window, or None.

    The window [start, stop) of a record with start > 2P sees the same play states as rows
    [2P, 2P + n) of u[:2P-2] ++ u[start-2:stop] (module docstring).
    """
    period, _ = input_period(record, rtol)
    if period is None or period < 3 or record.start <= 2 * period:
        return None
    start, stop = record.start, record.stop
    proxy = np.concatenate((record.u[: 2 * period - 2], record.u[start - 2: stop]))
    return proxy, slice(2 * period, 2 * period + (stop - start))
