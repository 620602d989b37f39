"""Identify the extension a diagnosis names, with the identifiers, and measure what it gains.

The extended models are registered models (``hysbench.models.extended``:
``mrpim+relaxation``, ``mrpim+delay``, ...); here they are identified with
``hysbench.identification.identify`` -- varpro where the extension keeps the
model partly linear (all but saturation), lsq otherwise -- on the
identification records over their whole length (a copy of the dataset whose
windows cover every sample; the records' weights k_m are kept), starting at
the screen's estimate, every parameter free. The base model is refitted the
same way, so the gain of the extension can be told apart from the gain of
fitting whole records.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Mapping, Sequence

import numpy as np

from hysbench.data.dataset import Dataset, Record
from hysbench.identification import Fit, identify
from hysbench.models import ExtendedModel, get_model
from hysbench.models.extended import extended_name, register_extensions
from hysbench.models.registry import list_models

from .residuals import RecordResidual

# Options of the final identification (the start is already close; see module docstring).
VARPRO_OPTIONS = {"n_candidates": 0, "n_starts": 1, "max_nfev": 8}
LARGE_SAMPLES = 500_000  # fit samples above which the local search gets LARGE_MAX_NFEV
LARGE_MAX_NFEV = 5
LSQ_OPTIONS = {"max_nfev": 30}


def whole_record(record: Record) -> Record:
    """The same record with its window covering every sample."""
    t = record.t
    return Record(file=record.file, t=t, u=record.u, y=record.y, role=record.role, frequency_hz=record.frequency_hz,
                  weight=record.weight, window=(float(t[0]), float(t[-1] + record.dt)))


def whole_record_dataset(dataset: Dataset) -> Dataset:
    return replace(dataset, records=[whole_record(r) for r in dataset.records])


def registered_extension(base: str, cause: str, hyper: Mapping | None = None,
                         base_hyperparameters: Mapping | None = None) -> ExtendedModel:
    """The registered ``base+cause`` model (registered on the fly for a base other than mrpim)."""
    name = extended_name(base, (cause,))
    if name not in list_models():
        register_extensions(base)
    return get_model(name, base_hyperparameters=dict(base_hyperparameters or {}), **dict(hyper or {}))


def identify_whole(model, dataset: Dataset, start: Mapping[str, float], seed: int, fit_on: Sequence[str],
                   bounds: Mapping | None = None) -> Fit:
    """Identify on the whole length of the ``fit_on`` records, from ``start`` (``bounds`` replace defaults)."""
    whole = whole_record_dataset(dataset)
    extra = {"bounds": dict(bounds)} if bounds else {}
    if model.has_linear_part:
        opts = dict(VARPRO_OPTIONS)
        if sum(r.t.size for r in dataset.records if r.file in set(fit_on)) > LARGE_SAMPLES:
            opts["max_nfev"] = LARGE_MAX_NFEV  # each evaluation builds every regressor over whole records
        return identify(model, whole, method="varpro", seed=seed, fit_on=list(fit_on), start=dict(start),
                        **extra, **opts)
    return identify(model, whole, method="lsq", seed=seed, fit_on=list(fit_on), start=dict(start), **extra,
                    **LSQ_OPTIONS)


def residuals_of_fit(fit: Fit, dataset: Dataset) -> list[RecordResidual]:
    return [RecordResidual(r, fit.predict(r)) for r in dataset.records]


def scores_by_file(residuals: Sequence[RecordResidual]) -> dict:
    return {rr.file: rr.scores() for rr in residuals}


def gain(before: Sequence[RecordResidual], after: Sequence[RecordResidual], role: str = "validation") -> dict:
    """What the extension gains on the records of ``role``: the share of the residual sum of squares
    it removes (whole records and scored windows), and the mean e_rms before and after."""
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
        "mean_e_rms_before": float(np.mean([s["e_rms"] for s in sb])),
        "mean_e_rms_after": float(np.mean([s["e_rms"] for s in sa])),
        "mean_e_rms_whole_before": float(np.mean([s["e_rms_whole"] for s in sb])),
        "mean_e_rms_whole_after": float(np.mean([s["e_rms_whole"] for s in sa])),
    }
