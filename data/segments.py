"""Records cut to their own samples, and records cut into segments.

Whatever uses a record's whole length (the diagnosis fits its causes on whole
records) must not see samples that belong to another record. One recording
listed twice in a manifest (an identification and a validation window) gives
two records that hold the same samples: ``own_samples`` cuts each to its
scored window. ``split_records`` cuts a record's scored window into
consecutive segments, each a record of its own, so that leave-one-record-out
works on a single long recording. A cut record starts from the models'
initial state; periodic records are cut at input minima, where that state
is closest to the one the history left.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from .dataset import Dataset, DatasetError, Record
from .protocol import period_samples


def same_recording(a: Record, b: Record) -> bool:
    """Two records holding the same samples (one file listed twice)."""
    return (a.t.size == b.t.size and np.array_equal(a.t, b.t) and np.array_equal(a.u, b.u)
            and np.array_equal(a.y, b.y))


def own_stretch(record: Record, records) -> slice:
    """The samples of ``record`` whose output a fit may read: its scored window widened on each side up to the
    nearest scored window of another record of the same recording (one file listed twice: that window is the
    other record's, e.g. its validation window); the whole record when no other record shares its samples,
    its window alone when another one overlaps it."""
    lo, hi = 0, record.t.size
    for other in records:
        if other is record or not same_recording(record, other):
            continue
        if other.stop <= record.start:
            lo = max(lo, other.stop)
        elif other.start >= record.stop:
            hi = min(hi, other.start)
        else:
            return record.scored
    return slice(lo, hi)


def cut(record: Record, start: int, stop: int, key: str | None = None) -> Record:
    """The samples [start, stop) of ``record`` as a record of their own, scored on all of them."""
    t = record.t[start:stop]
    return Record(file=key or record.file, t=t, u=record.u[start:stop], y=record.y[start:stop], role=record.role,
                  frequency_hz=record.frequency_hz, weight=record.weight,
                  window=(float(t[0]), float(t[-1] + record.dt)))


def _period(record: Record) -> int:
    return period_samples(record.frequency_hz, record.dt)


def input_minimum_from(record: Record, i: int) -> int:
    """The sample of the lowest input in the period from sample ``i`` (``i`` itself without a frequency).
    A cut record starts from the models' initial state; at the input's minimum the play operators' rest
    state is the one the history left them in, so a cut there costs least."""
    if not record.frequency_hz:
        return i
    return i + int(np.argmin(record.u[i:i + _period(record)]))


def own_samples(dataset: Dataset) -> Dataset:
    """Each record that shares its samples with another record cut to its scored window, from the
    window's first input minimum when a whole period remains after it; the others as they are (the same
    objects)."""
    records = dataset.records
    shared = [any(j != i and same_recording(r, s) for j, s in enumerate(records)) for i, r in enumerate(records)]
    if not any(shared):
        return dataset
    out = []
    for r, s in zip(records, shared):
        if not s:
            out.append(r)
            continue
        a = input_minimum_from(r, r.start)
        out.append(cut(r, a if r.frequency_hz and r.stop - a >= _period(r) else r.start, r.stop))
    return replace(dataset, records=out)


def segment_bounds(record: Record, segments: int) -> list[tuple[int, int]]:
    """[start, stop) of ``segments`` consecutive parts of the scored window: with a frequency, whole
    periods from the window's first input minimum (so each part starts at one; the periods left over go
    to the last part), else equal sample counts from the window's start."""
    if isinstance(segments, bool) or not isinstance(segments, (int, np.integer)) or segments < 2:
        raise DatasetError(f"segments must be an integer >= 2, got {segments!r}")
    if record.frequency_hz:
        period = _period(record)
        first = input_minimum_from(record, record.start)
        periods = (record.stop - first) // period
        if periods < segments:
            raise DatasetError(f"{record.file}: its scored window holds {periods} whole period(s) of "
                               f"{record.frequency_hz:g} Hz from its first input minimum: it cannot be cut into "
                               f"{segments} segments of whole periods")
        size = (periods // segments) * period
    else:
        first, n = record.start, record.n_scored
        if n < 2 * segments:
            raise DatasetError(f"{record.file}: its scored window holds {n} samples: too few for {segments} segments")
        size = n // segments
    edges = [first + k * size for k in range(segments)] + [record.stop]
    return list(zip(edges[:-1], edges[1:]))


def split_records(dataset: Dataset, segments: int, role: str = "identification") -> Dataset:
    """Every record of ``role`` replaced by ``segments`` records, its scored window cut by
    ``segment_bounds`` (keys STEM~k.SUFFIX, k = 1, 2, ...); samples before the window are dropped."""
    records = []
    for r in dataset.records:
        if r.role != role:
            records.append(r)
            continue
        path = Path(r.file)
        for k, (a, b) in enumerate(segment_bounds(r, segments), start=1):
            records.append(cut(r, a, b, str(path.with_name(f"{path.stem}~{k}{path.suffix}"))))
    return replace(dataset, records=records)
