"""One variant's fit, its scores and its leave-one-frequency-out cross-validation."""

from __future__ import annotations

import resource
import time
from types import SimpleNamespace
from typing import Sequence

import numpy as np

from hysbench.data.dataset import Dataset, Record
from hysbench.identification.criteria import lag1_autocorrelation
from hysbench.identification import Problem, SeparableProblem, identify
from hysbench.identification.problem import drive_time
from hysbench.models import DataScale, get_model

from hysbench.data.protocol import score_records

from .plan import Variant, frequency_groups

class FullBounds:
    """The default bounds ``identify`` would use when fitting the untrimmed records
    ``fit_on`` (they scale with max |u|, max |y| and the drive period of the fit records), so that a
    fit on trimmed records is the same problem: ``data_scale`` of the fit records, from each record's
    extremes and ``drive_time``, computed once."""

    def __init__(self, full: Dataset):
        self._proxies = {r.file: SimpleNamespace(
            u=np.array([r.u.min(), r.u.max()]), y=np.array([r.y.min(), r.y.max()]), time=drive_time(r))
            for r in full.records}

    def __call__(self, model, fit_on: Sequence[str]) -> dict:
        proxies = [self._proxies[f] for f in fit_on]
        scale = DataScale.of([p.u for p in proxies], [p.y for p in proxies], time=min(p.time for p in proxies))
        lo, hi = model.bounds(scale)
        return {n: [float(a), float(b)] for n, a, b in zip(model.param_names, lo, hi)}


class SharedColumns:
    """Window regressors of a superset model without envelopes (highest order, q on,
    N operators), computed once per record and input range; the regressors of any
    variant with that N and no envelopes are a subset of its columns, by name."""

    def __init__(self, n_operators: int, max_order: int):
        self.model = get_model("mrpim", poly_order=max_order, q_term=True, envelopes=False,
                               n_operators=n_operators)
        self.names = self.model.linear_names
        self._cache: dict = {}

    def blocks(self, model, records: Sequence[Record], in_range) -> list[np.ndarray]:
        idx = [self.names.index(n) for n in model.linear_names]
        out = []
        for r in records:
            key = (r.file, tuple(in_range))
            X = self._cache.get(key)
            if X is None:
                X = self._cache[key] = np.ascontiguousarray(self.model.windowed_regressors_batch(
                    r.u, r.dt, np.zeros((1, 0)), r.scored, in_range)[0])
            out.append(X[:, idx])
        return out


def _relabel(scores, fitted: set):
    return [type(s)(s.file, s.frequency_hz, "identification" if s.file in fitted else "validation", s.e_m, s.e_rms)
            for s in scores]


def fit_once(model, dataset: Dataset, fit_on: list[str], bounds: dict, seed: int, start: dict | None,
             options: dict, columns: SharedColumns | None = None) -> dict:
    """Identify ``model`` on the records ``fit_on``; scores of every record.

    With envelopes: ``identify(method="varpro")``. Without, the model has no
    nonlinear parameter and varpro is one linear solve: done here with the
    identifiers' ``SeparableProblem`` on regressors shared between the variants
    (``columns``) and varpro's search solve (``accurate=False``: the
    column-scaled normal equations by eigen-decomposition,
    the same ridge above condition 1e6) instead of ``identify``'s final QR, which
    costs more than the whole rest of such a fit. tests/test_ablation.py checks
    that both give the same fit.
    """
    t0 = time.perf_counter()
    fitted = set(fit_on)
    if model.nonlinear_names:
        fit = identify(model, dataset, method="varpro", seed=seed, fit_on=list(fit_on), bounds=bounds,
                       start=start, **options)
        params, fitness, scores = fit.params, fit.fitness, fit.records
        weak = len(fit.diagnostics.get("varpro", {}).get("weak_directions", []))
        evaluations, in_range, notes = fit.n_evaluations, fit.input_range, list(fit.notes)
    else:
        records = [r for r in dataset.records if r.file in fitted]
        problem = Problem.build(model, records, bounds, others=[r for r in dataset.records if r.file not in fitted])
        sep = SeparableProblem(problem)
        if columns is None:
            blocks = [model.windowed_regressors_batch(r.u, r.dt, np.zeros((1, 0)), r.scored, problem.input_range)[0]
                      for r in records]
        else:
            blocks = columns.blocks(model, records, problem.input_range)
        sol = sep.solve_blocks(blocks, accurate=False)
        params = model.unpack(problem.clip(sep.full_vector(np.zeros(0), sol.linear)))
        scores = _relabel(score_records(model, params, dataset.records, problem.input_range), fitted)
        fitness, weak, evaluations, in_range = sol.fitness, len(sol.weak_directions), 1, problem.input_range
        notes = ["linear solve regularised (condition number above the cap)"] if sol.regularised else []
    return {"params": params, "fitness": float(fitness), "scores": scores, "weak_directions": weak,
            "n_evaluations": int(evaluations), "input_range": tuple(in_range), "seconds": time.perf_counter() - t0,
            "notes": notes}

def _residual_autocorrelation(model, params, in_range, records: Sequence[Record]) -> list[float]:
    """Lag-1 autocorrelation of each record's residuals on its scored window."""
    return [lag1_autocorrelation(model.simulate(r.u, r.dt, params, input_range=in_range)[r.scored] - r.y[r.scored])
            for r in records]


def evaluate_variant(variant: Variant, dataset: Dataset, full: Dataset | None, seed: int,
                     full_options: dict, cv_options: dict, cross_validate: bool = True,
                     columns: SharedColumns | None = None, bounds: FullBounds | None = None) -> dict:
    """Full fit, scores, residual autocorrelation and leave-one-frequency-out CV of one variant.

    ``dataset`` is what is fitted (possibly history-trimmed); ``full`` the
    untrimmed dataset for bounds and the re-scoring check (None: the same).
    A cross-validation fit is the full fit's procedure on the other records
    (same start, candidates and seed), blind to the left-out record.
    """
    full = full or dataset
    bounds = bounds or FullBounds(full)
    model = variant.model()
    ident = [r.file for r in dataset.identification]
    main_bounds = bounds(model, ident)
    main = fit_once(model, dataset, ident, main_bounds, seed, None, full_options, columns)
    rescore_gap = 0.0
    if full is not dataset:
        again = score_records(model, main["params"], full.records, main["input_range"])
        rescore_gap = max(abs(a.e_rms - b.e_rms) for a, b in zip(again, main["scores"]))
    id_records = dataset.identification
    rho = _residual_autocorrelation(model, main["params"], main["input_range"], id_records)
    out = {
        "name": variant.name, "order": variant.order, "q_term": variant.q_term, "envelopes": variant.envelopes,
        "n_operators": variant.n_operators, "n_params": model.n_params,
        "n_params_identifiable": model.n_params - main["weak_directions"],
        "params": main["params"], "fitness": main["fitness"],
        "n_scored": int(sum(r.n_scored for r in id_records)),
        "id_weights": [(int(r.n_scored), float(r.weight)) for r in id_records],
        "residual_lag1": {r.file: p for r, p in zip(id_records, rho)},
        "records": [s.as_dict() for s in main["scores"]],
        "fit_seconds": main["seconds"], "n_evaluations": main["n_evaluations"], "notes": main["notes"],
        "rescore_gap": rescore_gap,
        "at_bounds": {n: main_bounds[n] for n in model.nonlinear_names
                      if min(abs(main["params"][n] - b) for b in main_bounds[n])
                      <= 1e-6 * (main_bounds[n][1] - main_bounds[n][0])},
    }
    if cross_validate:
        folds = []
        t1 = time.perf_counter()
        for label, files in frequency_groups(dataset):
            fit_on = [r.file for r in dataset.records if r.file not in files]
            if not fit_on:
                continue
            fold = fit_once(model, dataset, fit_on, bounds(model, fit_on), seed, None, cv_options, columns)
            left = [s for s in fold["scores"] if s.file in files]
            folds.append({"left_out": label, "files": list(files),
                          "e_rms": float(np.mean([s.e_rms for s in left])),
                          "e_m": float(max(s.e_m for s in left)),
                          "nonlinear": {n: fold["params"][n] for n in model.nonlinear_names},
                          "n_evaluations": fold["n_evaluations"]})
        out["cv_folds"] = folds
        out["cv_seconds"] = time.perf_counter() - t1
    return out


def evaluate_task(variants: list[Variant], dataset: Dataset, full: Dataset | None, seed: int,
                  full_options: dict, cv_options: dict) -> list[dict]:
    """One unit of work: a variant with envelopes, or every variant without envelopes
    sharing one N (their regressors are shared)."""
    columns = None
    if all(not v.envelopes for v in variants):
        columns = SharedColumns(variants[0].n_operators, max(v.order for v in variants))
    bounds = FullBounds(full or dataset)
    return [evaluate_variant(v, dataset, full, seed, full_options, cv_options, columns=columns, bounds=bounds)
            for v in variants]


def _cpu_seconds() -> float:
    """User + system CPU time of this process and its finished worker processes."""
    own, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + kids.ru_utime + kids.ru_stime
