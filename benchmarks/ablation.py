"""Ablation of MRPIM: which of its parts earn their parameters on a dataset.

Variants of the registered ``mrpim`` model differ in four factors: the order
of the input polynomial (0..6), the q V'' term (on/off), the dynamic envelopes
(on/off; off is gamma = lambda = 0, the classical play operators) and the
number of play operators N. They are varied one factor at a time around a
reference (the paper's choice: order 4, q on, envelopes on, N = 13), plus the
full grid order x q x envelopes at the reference N. Identical variants are
fitted once.

Every variant is identified by variable projection (``identify(..., "varpro")``;
variants without envelopes, which have no nonlinear parameter, by varpro's
linear solve on shared regressors, see ``fit_once``) on the dataset's
identification records and scored on every record; then leave-one-frequency-out
cross-validation fits it, by the same procedure, on all records but those of
one frequency (``fit_on``) and predicts that frequency, for every frequency.

Definitions (also written into the JSON's ``definitions``):

* n_params: the model's parameters, output offset included (every variant has it).
* e_m, e_rms: eq. 10 per record, percent of the measured peak-to-peak over the
  scored window; ``*_e_rms`` is the mean over the records of that role,
  ``*_e_m`` the largest.
* cv_e_rms: mean over the left-out frequencies of the left-out records' e_rms.
  Each fitted record keeps the weight k_m the dataset gives it (Table 1's
  4, 1, 4, 1 for the identification frequencies and, in the protocol, 1 for
  the others); the weights are not renormalised when a frequency is left out
  (a common factor does not move eq. 9's minimum).
* AIC, BIC: a Gaussian likelihood with eq. 9's weighting on the identification
  records, i.e. residual r_mi ~ N(0, sigma^2 n_m / k_m) independently, sigma^2
  at its maximum-likelihood value f / n (f: eq. 9 at the fit, n: number of scored
  samples). Then -2 ln L = n ln(2 pi f / n) + n - sum_m n_m ln(k_m / n_m), and
  AIC = -2 ln L + 2 k, BIC = -2 ln L + k ln n with k = the model's parameters + 1
  (sigma). Residuals are autocorrelated (model error is smooth and periodic),
  so the n samples carry far less than n independent pieces of information:
  ``n_effective`` (an AR(1) estimate, sum_m n_m (1 - rho_m) / (1 + rho_m) with
  rho_m the lag-1 autocorrelation of the reference variant's residuals) and
  ``aic_effective``/``bic_effective`` (the likelihood term scaled by
  n_effective / n) show how much that weakens the case for bigger models.

Speed: an MRPIM's play operators run from a record's first sample, but a
sampled periodic input (the protocol's records) makes their state periodic after
one period (the state map over one period is a composition of clamps, hence
idempotent). ``trim_history`` therefore drops whole periods before the scored
window, keeping at least one, when the input is periodic from the first sample
(checked); the regressors on the window are then the same (checked at run time,
and every full fit is re-scored on the untrimmed records).
"""

from __future__ import annotations

import math
import os
import resource
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from types import SimpleNamespace
from multiprocessing import get_context
from typing import Iterable, Sequence

import numpy as np

from hysbench.data.dataset import Dataset, Record
from hysbench.identification import Problem, SeparableProblem, data_scale, identify
from hysbench.models import get_model
from hysbench.models.errors import HysbenchError

from hysbench.data.protocol import score_records

ORDERS = tuple(range(7))
N_OPERATORS = (3, 5, 9, 13, 17, 25)
FACTORS = ("order", "q_term", "envelopes", "n_operators")
# A difference between two variants' cross-validated e_rms counts when it exceeds
# one standard error of the paired per-frequency differences and this fraction
# of the smaller of the two.
TIE_RELATIVE = 0.02
# varpro settings: (gamma, lambda) searched from the default start and 8 Sobol
# candidates, one local search from the best. A cross-validation fit repeats
# exactly this: starting it from the full fit's optimum would let the left-out
# record steer the fold's search (the full fit saw it).
FULL_FIT_OPTIONS = {"n_candidates": 8, "n_starts": 1}
CV_FIT_OPTIONS = dict(FULL_FIT_OPTIONS)
TRIM_CHECK_RTOL = 1e-9


class AblationError(HysbenchError):
    """A dataset or setting the ablation cannot work with."""


@dataclass(frozen=True, order=True)
class Variant:
    """One MRPIM configuration."""

    order: int
    q_term: bool
    envelopes: bool
    n_operators: int

    @property
    def name(self) -> str:
        return f"o{self.order}{'-q' if self.q_term else ''}{'-env' if self.envelopes else ''}-N{self.n_operators}"

    def model(self):
        return get_model("mrpim", poly_order=self.order, q_term=self.q_term, envelopes=self.envelopes,
                         n_operators=self.n_operators)

    def with_(self, **changes) -> "Variant":
        d = {"order": self.order, "q_term": self.q_term, "envelopes": self.envelopes,
             "n_operators": self.n_operators}
        d.update(changes)
        return Variant(**d)


PAPER = Variant(4, True, True, 13)


def plan_variants(reference: Variant = PAPER, orders: Sequence[int] = ORDERS,
                  n_operators: Sequence[int] = N_OPERATORS, factors: Iterable[str] = FACTORS,
                  grid: bool = True) -> list[tuple[Variant, list[str]]]:
    """Distinct variants and the families they belong to ("order", "q_term",
    "envelopes", "n_operators": one factor varied around ``reference``; "grid":
    order x q x envelopes at the reference's N)."""
    factors = list(factors)
    unknown = [f for f in factors if f not in FACTORS]
    if unknown:
        raise AblationError(f"unknown factor(s) {', '.join(unknown)}; factors: {', '.join(FACTORS)}")
    families: dict[Variant, list[str]] = {reference: []}

    def add(v: Variant, family: str):
        fams = families.setdefault(v, [])
        if family not in fams:
            fams.append(family)

    for f in factors:
        add(reference, f)
        if f == "order":
            for k in orders:
                add(reference.with_(order=int(k)), f)
        elif f == "q_term":
            add(reference.with_(q_term=not reference.q_term), f)
        elif f == "envelopes":
            add(reference.with_(envelopes=not reference.envelopes), f)
        else:
            for n in n_operators:
                add(reference.with_(n_operators=int(n)), f)
    if grid:
        for k in orders:
            for q in (False, True):
                for e in (False, True):
                    add(Variant(int(k), q, e, reference.n_operators), "grid")
    for v in families:
        v.model()  # refuses bad settings early (ModelError)
    return list(families.items())


# --- history trimming -----------------------------------------------------------------
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


# --- one fit ----------------------------------------------------------------------------
class FullBounds:
    """The default bounds ``identify`` would use when fitting the untrimmed records
    ``fit_on`` (they scale with max |u|, max |y| of the fit records), so that a
    fit on trimmed records is the same problem. ``data_scale`` is called on
    two-sample stand-ins holding each record's extremes, computed once."""

    def __init__(self, full: Dataset):
        self._proxies = {r.file: SimpleNamespace(
            file=r.file, u=np.array([r.u.min(), r.u.max()]), y=np.array([r.y.min(), r.y.max()]),
            frequency_hz=r.frequency_hz, n_scored=r.n_scored, dt=r.dt) for r in full.records}

    def __call__(self, model, fit_on: Sequence[str]) -> dict:
        lo, hi = model.bounds(data_scale([self._proxies[f] for f in fit_on]))
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
        problem = Problem.build(model, records, bounds)
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


def frequency_groups(dataset: Dataset) -> list[tuple[str, list[str]]]:
    """(label, files) of each frequency (records without one are their own group)."""
    groups: dict[str, list[str]] = {}
    for r in dataset.records:
        label = f"{r.frequency_hz:g} Hz" if r.frequency_hz else r.file
        groups.setdefault(label, []).append(r.file)
    return list(groups.items())


def _residual_autocorrelation(model, params, in_range, records: Sequence[Record]) -> list[float]:
    """Lag-1 autocorrelation of each record's residuals on its scored window."""
    out = []
    for r in records:
        e = model.simulate(r.u, r.dt, params, input_range=in_range)[r.scored] - r.y[r.scored]
        e = e - e.mean()
        den = float(e @ e)
        out.append(float(e[1:] @ e[:-1]) / den if den > 0 else 0.0)
    return out


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


def plan_tasks(variants: Sequence[Variant]) -> list[list[Variant]]:
    """Tasks, costly first (envelopes mean a nonlinear search; cost grows with N), for load balance."""
    tasks = [[v] for v in sorted((v for v in variants if v.envelopes),
                                 key=lambda v: (-v.n_operators, not v.q_term, -v.order))]
    by_n: dict[int, list[Variant]] = {}
    for v in variants:
        if not v.envelopes:
            by_n.setdefault(v.n_operators, []).append(v)
    tasks += [sorted(vs) for _, vs in sorted(by_n.items(), reverse=True)]
    return tasks


# --- the ablation -------------------------------------------------------------------------
_WORKER: dict = {}


def _init_worker(dataset, full, seed, full_options, cv_options):
    import numba

    numba.set_num_threads(1)
    _WORKER.update(dataset=dataset, full=full, seed=seed, full_options=full_options, cv_options=cv_options)


def _work(task: list[Variant]) -> list[dict]:
    w = _WORKER
    return evaluate_task(task, w["dataset"], w["full"], w["seed"], w["full_options"], w["cv_options"])


def run_ablation(dataset: Dataset, *, reference: Variant = PAPER, orders: Sequence[int] = ORDERS,
                 n_operators: Sequence[int] = N_OPERATORS, factors: Iterable[str] = FACTORS, grid: bool = True,
                 seed: int = 0, jobs: int = 1, trim: bool = True, full_options: dict | None = None,
                 cv_options: dict | None = None, progress=None) -> dict:
    """Fit, score and cross-validate every planned variant; returns the JSON-ready result."""
    t_start, cpu_start = time.perf_counter(), _cpu_seconds()
    if not dataset.identification:
        raise AblationError(f"dataset {dataset.name!r} has no identification records")
    groups = frequency_groups(dataset)
    if len(groups) < 2:
        raise AblationError(f"dataset {dataset.name!r}: leave-one-frequency-out needs records of at least two "
                            f"frequencies, it has {len(groups)}")
    if not (isinstance(jobs, int) and jobs >= 1):
        raise AblationError(f"jobs must be a positive integer, got {jobs!r}")
    plan = plan_variants(reference, orders, n_operators, factors, grid)
    full_options = {**FULL_FIT_OPTIONS, **(full_options or {})}
    cv_options = {**CV_FIT_OPTIONS, **(cv_options or {})}
    trim_info, trim_check = [], None
    fitted = dataset
    if trim:
        fitted, trim_info = trim_history(dataset)
        if any(i["trimmed"] for i in trim_info):
            n_max = max(v.n_operators for v, _ in plan)
            trim_check = check_trim(dataset, fitted, Variant(0, False, True, n_max))
            if trim_check > TRIM_CHECK_RTOL * 1e3:
                fitted = dataset
                for i in trim_info:
                    i.update(trimmed=False, reason=f"trim check failed (relative regressor difference "
                                                   f"{trim_check:.2e}): kept whole")
    variants = [v for v, _ in plan]
    results: dict[Variant, dict] = {}
    t_fit = time.perf_counter()
    tasks = plan_tasks(variants)

    def collect(task, rows):
        for v, row in zip(task, rows):
            results[v] = row
            if progress:
                progress(v, row)

    if jobs == 1 or len(tasks) == 1:
        for task in tasks:
            collect(task, evaluate_task(task, fitted, dataset, seed, full_options, cv_options))
    else:
        ctx = get_context("spawn")  # numba's threads do not survive fork
        with ProcessPoolExecutor(max_workers=min(jobs, len(tasks)), mp_context=ctx, initializer=_init_worker,
                                 initargs=(fitted, dataset, seed, full_options, cv_options)) as pool:
            for task, rows in zip(tasks, pool.map(_work, tasks)):
                collect(task, rows)
    fit_wall = time.perf_counter() - t_fit
    rows = []
    for v, fams in plan:
        row = results[v]
        row["families"] = fams
        row["paper"] = v == PAPER
        row["reference"] = v == reference
        rows.append(row)
    _summarise(rows, dataset, reference)
    result = {
        "format": "hysbench-ablation/1",
        "dataset": dataset.name,
        "dataset_hash": dataset.content_hash(),
        "dataset_description": dataset.description,
        "records": [{"file": r.file, "frequency_hz": r.frequency_hz, "role": r.role, "weight": r.weight,
                     "n_scored": r.n_scored} for r in dataset.records],
        "reference": reference.name,
        "settings": {"seed": seed, "jobs": jobs, "method": "varpro", "full_fit": full_options,
                     "cv_fit": cv_options, "tie_relative": TIE_RELATIVE, "trim": trim,
                     "orders": list(orders), "n_operators": list(n_operators), "factors": list(factors),
                     "grid": grid},
        "definitions": DEFINITIONS,
        "history_trim": {"records": trim_info, "regressor_check_relative": trim_check,
                         "rescore_gap_e_rms": max((r["rescore_gap"] for r in rows), default=0.0)},
        "variants": rows,
        "timing": {"total_seconds": time.perf_counter() - t_start, "fit_wall_seconds": fit_wall,
                   "cpu_seconds": _cpu_seconds() - cpu_start, "load_average": list(os.getloadavg()),
                   "cores": os.cpu_count(),
                   "n_variants": len(rows), "n_fits": sum(1 + len(r.get("cv_folds", [])) for r in rows),
                   "fit_seconds_sum": sum(r["fit_seconds"] + r.get("cv_seconds", 0.0) for r in rows)},
    }
    result["verdicts"] = verdicts(result)
    result["conclusions"] = conclusions(result)
    return result


DEFINITIONS = {
    "e_rms": "eq. 10 per record, percent of the measured peak-to-peak in the scored window",
    "identification_e_rms": "mean over identification records of e_rms (full fit); *_e_m: largest e_m",
    "validation_e_rms": "mean over validation records of e_rms (full fit); *_e_m: largest e_m",
    "cv_e_rms": "mean over frequencies of the e_rms of that frequency's records when the variant is fitted on "
                "all other records (leave-one-frequency-out); each fitted record keeps its dataset weight k_m, "
                "not renormalised; cv_e_m: largest e_m of the left-out records",
    "aic": "-2 ln L + 2 k; L Gaussian with eq. 9's weighting (r_mi ~ N(0, sigma^2 n_m / k_m)), sigma^2 = f / n "
           "(ML), f = eq. 9 at the fit, n = scored identification samples; -2 ln L = n ln(2 pi f / n) + n - "
           "sum_m n_m ln(k_m / n_m); k = n_params + 1",
    "bic": "-2 ln L + k ln n (same L, k, n)",
    "n_effective": "sum_m n_m (1 - rho_m) / (1 + rho_m), rho_m = lag-1 autocorrelation of the reference "
                   "variant's residuals on identification record m (AR(1) approximation)",
    "aic_effective": "(n_effective / n) (-2 ln L) + 2 k: AIC as if only n_effective samples were independent; "
                     "bic_effective likewise with k ln n_effective",
    "n_params_identifiable": "n_params minus the directions varpro's linear solve found below s_max / 1e6 "
                             "(numerically undetermined, e.g. operators whose threshold exceeds the input's "
                             "swing are constant, like the offset)",
    "difference_counts": f"a difference in cv_e_rms counts when the mean paired per-frequency difference exceeds "
                         f"its standard error and {TIE_RELATIVE:.0%} of the smaller cv_e_rms",
}


def _summarise(rows: list[dict], dataset: Dataset, reference: Variant) -> None:
    """Aggregate scores, AIC/BIC and their autocorrelation-aware forms, in place."""
    ref = next(r for r in rows if r["reference"])
    neff = 0.0
    for (n_m, _), rho in zip(ref["id_weights"], ref["residual_lag1"].values()):
        rho = min(max(rho, 0.0), 0.999999)
        neff += n_m * (1.0 - rho) / (1.0 + rho)
    for row in rows:
        recs = row["records"]
        for role in ("identification", "validation"):
            sel = [s for s in recs if s["role"] == role]
            row[f"{role}_e_rms"] = float(np.mean([s["e_rms"] for s in sel])) if sel else None
            row[f"{role}_e_m"] = float(max(s["e_m"] for s in sel)) if sel else None
        folds = row.get("cv_folds")
        if folds:
            row["cv_e_rms"] = float(np.mean([f["e_rms"] for f in folds]))
            row["cv_e_rms_worst"] = float(max(f["e_rms"] for f in folds))
            row["cv_e_m"] = float(max(f["e_m"] for f in folds))
        else:
            row["cv_e_rms"] = row["cv_e_rms_worst"] = row["cv_e_m"] = None
        n = row["n_scored"]
        f = row["fitness"]
        k = row["n_params"] + 1
        const = n - sum(n_m * math.log(k_m / n_m) for n_m, k_m in row["id_weights"] if k_m > 0)
        m2ll = n * math.log(2.0 * math.pi * f / n) + const if f > 0 else -math.inf
        row["aic"] = m2ll + 2 * k
        row["bic"] = m2ll + k * math.log(n)
        row["n_effective"] = neff
        row["aic_effective"] = (neff / n) * m2ll + 2 * k
        row["bic_effective"] = (neff / n) * m2ll + k * math.log(max(neff, 1.0))
    for key in ("aic", "bic", "aic_effective", "bic_effective"):
        best = min(r[key] for r in rows)
        for r in rows:
            r[f"delta_{key}"] = r[key] - best


# --- what the numbers say ------------------------------------------------------------------
def compare(a: dict, b: dict) -> dict:
    """Paired comparison of two variants' cross-validation: d = b - a per frequency."""
    fa = {f["left_out"]: f["e_rms"] for f in a["cv_folds"]}
    fb = {f["left_out"]: f["e_rms"] for f in b["cv_folds"]}
    common = [k for k in fa if k in fb]
    d = np.array([fb[k] - fa[k] for k in common])
    mean = float(d.mean())
    se = float(d.std(ddof=1) / math.sqrt(d.size)) if d.size > 1 else 0.0
    margin = max(se, TIE_RELATIVE * min(a["cv_e_rms"], b["cv_e_rms"]))
    verdict = "worse" if mean > margin else "better" if mean < -margin else "tie"
    return {"mean": mean, "se": se, "margin": margin, "verdict": verdict,
            "n_worse": int(np.sum(d > 0)), "n": int(d.size)}


def _family(rows: list[dict], family: str) -> list[dict]:
    return [r for r in rows if family in r["families"] and r.get("cv_folds")]


def _smallest_adequate(rows: list[dict], key: str) -> tuple[dict, dict]:
    """(best by cv_e_rms, smallest ``key`` not worse than the best)."""
    best = min(rows, key=lambda r: r["cv_e_rms"])
    for r in sorted(rows, key=lambda r: r[key]):
        if r is best or compare(best, r)["verdict"] != "worse":
            return best, r
    return best, best


def verdicts(result: dict) -> dict:
    """The verdicts behind the conclusions, as data: for q_term and envelopes, what removing the part
    does to the cross-validated error ("worse", "better" or "tie"); for order and n_operators, the
    smallest value not worse than the best."""
    rows = result["variants"]
    ref = next(r for r in rows if r["reference"])
    out = {}
    if not ref.get("cv_folds"):
        return out
    for factor in ("q_term", "envelopes"):
        other = next((r for r in _family(rows, factor) if r[factor] != ref[factor]), None)
        if other is not None:
            with_it, without = (ref, other) if ref[factor] else (other, ref)
            out[factor] = {"without": compare(with_it, without)["verdict"]}
    for factor in ("order", "n_operators"):
        fam = _family(rows, factor)
        if len(fam) >= 2:
            best, enough = _smallest_adequate(fam, factor)
            out[factor] = {"enough": enough[factor], "best": best[factor]}
    return out


def conclusions(result: dict) -> list[str]:
    """Plain statements, computed from the numbers, of which parts earn their keep."""
    rows = result["variants"]
    ref = next(r for r in rows if r["reference"])
    if not ref.get("cv_folds"):
        return []
    out = []

    def fmt(r):
        return f"{r['cv_e_rms']:.3f} %"

    for factor, label, plural in (("q_term", "The q V'' term", False),
                                  ("envelopes", "The dynamic envelopes (gamma, lambda)", True)):
        fam = _family(rows, factor)
        other = next((r for r in fam if r[factor] != ref[factor]), None)
        if other is None:
            continue
        with_it, without = (ref, other) if ref[factor] else (other, ref)
        c = compare(with_it, without)
        extra = with_it["n_params"] - without["n_params"]
        detail = (f"cross-validated e_rms {fmt(with_it)} with, {fmt(without)} without "
                  f"(mean paired difference {c['mean']:+.3f} ± {c['se']:.3f} points; worse without at "
                  f"{c['n_worse']} of {c['n']} left-out frequencies)")
        if with_it["validation_e_rms"] is not None:
            detail += (f"; on the validation records {with_it['validation_e_rms']:.3f} % with, "
                       f"{without['validation_e_rms']:.3f} % without")
        verb = ("earn their" if plural else "earns its") + " keep"
        if c["verdict"] == "worse":
            out.append(f"{label} {verb} ({extra} parameter{'s' if extra != 1 else ''}): {detail}.")
        elif c["verdict"] == "better":
            out.append(f"{label} {'cost' if plural else 'costs'} accuracy on frequencies left out of the fit: "
                       f"{detail}.")
        else:
            out.append(f"{label} {'make' if plural else 'makes'} no difference that counts on left-out "
                       f"frequencies: {detail}.")
    for factor, label in (("order", "polynomial order"), ("n_operators", "number of play operators")):
        fam = _family(rows, factor)
        if len(fam) < 2:
            continue
        best, enough = _smallest_adequate(fam, factor)
        val = ref[factor]
        cmp_ref = compare(enough, ref) if enough is not ref else None
        name = factor_name(factor)
        if enough is best:
            levels = ", ".join(str(r[factor]) for r in sorted(fam, key=lambda r: r[factor]))
            s = (f"The {label}: {name} = {enough[factor]} is enough: it has the lowest cross-validated e_rms "
                 f"({fmt(enough)}) of {name} = {levels}")
        else:
            c = compare(best, enough)
            s = (f"The {label}: {name} = {enough[factor]} is enough: its cross-validated e_rms {fmt(enough)} is within "
                 f"the margin ({c['margin']:.3f} points; mean paired difference {c['mean']:+.3f}) of the best, "
                 f"{name} = {best[factor]} with {fmt(best)}"
                 + (", and smaller values are worse by more" if any(r[factor] < enough[factor] for r in fam) else ""))
        if enough[factor] == val:
            s += f"; the reference's {val} is exactly that."
        elif enough[factor] < val:
            verdict = {"worse": "and fits left-out frequencies worse", "better": "and fits them better",
                       "tie": "at no measurable gain"}[cmp_ref["verdict"]] if cmp_ref else ""
            s += (f"; the reference's {val} adds {ref['n_params'] - enough['n_params']} parameters "
                  f"{verdict} ({fmt(ref)}).")
        else:
            s += f"; the reference's {val} is too small ({fmt(ref)})."
        out.append(s)
    grid = _family(rows, "grid")
    if grid:
        best = min(grid, key=lambda r: r["cv_e_rms"])
        out.append(f"Over the grid order x q x envelopes (N = {ref['n_operators']}), the lowest cross-validated e_rms "
                   f"is {best['name']} ({fmt(best)}, {best['n_params']} parameters); the reference {ref['name']} has "
                   f"{fmt(ref)} ({ref['n_params']} parameters).")
    bound_hits = [r for r in rows if r.get("at_bounds")]
    if bound_hits:
        names = sorted({n for r in bound_hits for n in r["at_bounds"]})
        first = next((r for r in bound_hits if r["reference"]), bound_hits[0])
        among = " (the reference among them)" if any(r is ref for r in bound_hits) else ""
        out.append(f"In {len(bound_hits)} of {len(rows)} variants{among} the fitted {' and/or '.join(names)} {'sit' if len(names) > 1 else 'sits'} at a bound of "
                   f"the default search box (e.g. {first['name']}: "
                   + ", ".join(f"{n} in [{lo:.3g}, {hi:.3g}]" for n, (lo, hi) in first["at_bounds"].items())
                   + "): those variants' errors are for envelopes within these bounds and might be lower with "
                     "wider ones.")
    by_bic = min(rows, key=lambda r: r["bic"])
    by_bice = min(rows, key=lambda r: r["bic_effective"])
    best_cv = min((r for r in rows if r.get("cv_folds")), key=lambda r: r["cv_e_rms"])
    out.append(f"BIC on the identification records prefers {by_bic['name']} ({by_bic['n_params']} parameters); "
               f"with the sample count cut to the {ref['n_effective']:.0f} effectively independent residuals "
               f"(of {ref['n_scored']}) it prefers {by_bice['name']} ({by_bice['n_params']} parameters); "
               f"cross-validation prefers {best_cv['name']} ({best_cv['n_params']} parameters).")
    return out


def factor_name(factor: str) -> str:
    return {"order": "order", "n_operators": "N", "q_term": "q", "envelopes": "envelopes"}[factor]
