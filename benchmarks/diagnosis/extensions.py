"""Identify the extension a diagnosis names (a registered model, ``hysbench.models.extended``) with
``hysbench.identification.identify`` on the identification records' whole length, from the screen's estimate, on
the screen's rows, and measure what it gains. The base is refitted the same way, so the extension's gain is told
apart from the gain of fitting whole records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import numpy as np

from hysbench.data.dataset import Dataset, Record
from hysbench.data.segments import cut
from hysbench.identification import Fit, identify
from hysbench.models import ExtendedModel, get_model
from hysbench.models.extended import extended_name, register_extensions
from hysbench.models.registry import list_models

from .residuals import RecordResidual, gain_z

# the final identification's options (the start is already close)
VARPRO_OPTIONS = {"n_candidates": 0, "n_starts": 1, "max_nfev": 8}
LSQ_OPTIONS = {"max_nfev": 30}


@dataclass
class SampledRecord(Record):
    """A record fitted on a fixed subset of its samples (``rows``, increasing); every model
    runs over all of them. What is scored is the same subset."""
    rows: np.ndarray | None = None

    @property
    def scored(self):
        return self.rows if self.rows is not None else super().scored

    @property
    def n_scored(self) -> int:
        return int(self.rows.size) if self.rows is not None else super().n_scored


def whole_record_dataset(dataset: Dataset, rows: Mapping[str, np.ndarray] | None = None) -> Dataset:
    """Every record's window covering all its samples; records named in ``rows`` fitted on those rows."""
    rows = dict(rows or {})
    records = []
    for r in dataset.records:
        w = cut(r, 0, r.t.size)
        if r.file in rows and rows[r.file].size < r.t.size:
            w = SampledRecord(file=w.file, t=w.t, u=w.u, y=w.y, role=w.role, frequency_hz=w.frequency_hz,
                              weight=w.weight, window=w.window, rows=np.asarray(rows[r.file], dtype=np.int64))
        records.append(w)
    name = dataset.name + (" (whole records, sampled rows)" if rows else " (whole records)")
    return replace(dataset, name=name, records=records)


def registered_extension(base: str, cause: str, hyper: Mapping | None = None,
                         base_hyperparameters: Mapping | None = None) -> ExtendedModel:
    """The registered ``base+cause`` model (registered on the fly for a base other than mrpim)."""
    name = extended_name(base, (cause,))
    if name not in list_models():
        register_extensions(base)
    return get_model(name, base_hyperparameters=dict(base_hyperparameters or {}), **dict(hyper or {}))


def identify_whole(model, dataset: Dataset, start: Mapping[str, float], seed: int, fit_on: Sequence[str],
                   bounds: Mapping | None = None, rows: Mapping[str, np.ndarray] | None = None) -> Fit:
    """Identify on the whole length of the ``fit_on`` records (on ``rows`` of those named there), from
    ``start`` (``bounds`` replace defaults)."""
    whole = whole_record_dataset(dataset, rows)
    extra = {"bounds": dict(bounds)} if bounds else {}
    method, options = ("varpro", VARPRO_OPTIONS) if model.has_linear_part else ("lsq", LSQ_OPTIONS)
    return identify(model, whole, method=method, seed=seed, fit_on=list(fit_on), start=dict(start), **extra,
                    **options)


def residuals_of_fit(fit: Fit, dataset: Dataset) -> list[RecordResidual]:
    return [RecordResidual(r, fit.predict(r)) for r in dataset.records]


def scores_by_file(residuals: Sequence[RecordResidual]) -> dict:
    return {rr.file: rr.scores() for rr in residuals}


def gain(before: Sequence[RecordResidual], after: Sequence[RecordResidual], role: str = "validation") -> dict:
    """What the extension gains on the records of ``role``: the share of the residual sum of squares it removes,
    its z against the records' own noise (``residuals.gain_z``) and the mean e_rms before and after."""
    b = [rr for rr in before if rr.record.role == role]
    a = {rr.file: rr for rr in after}
    if not b:
        return {}
    ss_b = sum(float(rr.residual @ rr.residual) for rr in b)
    ss_a = sum(float(a[rr.file].residual @ a[rr.file].residual) for rr in b)
    w_b = sum(float(np.sum(rr.residual[rr.record.scored] ** 2)) for rr in b)
    w_a = sum(float(np.sum(a[rr.file].residual[rr.record.scored] ** 2)) for rr in b)
    sb = [rr.scores() for rr in b]
    sa = [a[rr.file].scores() for rr in b]
    return {
        "records": [rr.file for rr in b],
        "explained_whole": 1.0 - ss_a / ss_b if ss_b > 0 else math.nan,
        "explained_window": 1.0 - w_a / w_b if w_b > 0 else math.nan,
        "z_whole": gain_z([(rr.residual, a[rr.file].residual) for rr in b]),
        "mean_e_rms_before": float(np.mean([s["e_rms"] for s in sb])),
        "mean_e_rms_after": float(np.mean([s["e_rms"] for s in sa])),
        "mean_e_rms_whole_before": float(np.mean([s["e_rms_whole"] for s in sb])),
        "mean_e_rms_whole_after": float(np.mean([s["e_rms_whole"] for s in sa])),
    }
