"""The ablation run: every variant, in worker processes, summarised."""

from __future__ import annotations

import os
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from typing import Iterable, Sequence


from hysbench.data.dataset import Dataset

from .conclusions import conclusions
from .criteria import _summarise, verdicts
from .fit import _cpu_seconds, evaluate_task
from hysbench.data.periodic import trim_history

from .history import check_trim
from .plan import (AblationError, CV_FIT_OPTIONS, FACTORS, FULL_FIT_OPTIONS, N_OPERATORS, ORDERS, PAPER,
                   TIE_RELATIVE, TRIM_CHECK_RTOL, Variant, frequency_groups, plan_tasks, plan_variants)

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
