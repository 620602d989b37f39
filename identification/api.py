"""``identify(model, dataset, method, seed, **options) -> Fit``: every identifier behind one call.

Methods (see each module's docstring):

* ``varpro`` -- separable least squares: exact solve of the linear
  parameters, multi-start search over the nonlinear ones. Needs a model with
  a linear part; a model with no nonlinear parameter is one linear solve.
* ``mpso`` -- modified particle swarm over all parameters (the paper's).
* ``lsq`` -- scipy.optimize.least_squares over all parameters.
* chains ``A+B`` run B from A's result; ``varpro+lsq`` and ``mpso+lsq`` are
  the polished forms (lsq starts exactly at the previous stage's parameters).
* ``auto`` -- ``varpro`` for a model with a linear part, else ``lsq``.

Options common to all methods:

* ``fit_on``: file names of the records to fit (default: the dataset's
  identification records). Records not fitted are scored as validation,
  records fitted as identification (leave-one-frequency-out and similar).
* ``bounds``: {name: [low, high]} replacing default bounds (which scale with
  ``DataScale`` of the fit records: max |u|, max |y|, shortest drive period).
* ``start``: {name: value}, a partial start point (default: the model's
  default parameters), clipped into the bounds.

Method options (see ``OPTIONS`` in each module) may be given plainly, going
to every stage that knows them, or prefixed by a stage (``lsq.max_nfev``).
"""

from __future__ import annotations

import math
import os
import time
import weakref
from importlib import metadata
from typing import Mapping

import numpy as np
from threadpoolctl import threadpool_limits

from hysbench.data.protocol import score_records
from hysbench.data.dataset import Dataset, load_dataset
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel

from . import lsq, mpso, varpro
from .criteria import aic, bic
from .errors import IdentificationError
from .fit import Fit
from .problem import Problem

STAGES = {"varpro": varpro, "mpso": mpso, "lsq": lsq}
METHODS = ("varpro", "mpso", "lsq", "varpro+lsq", "mpso+lsq")
COMMON_OPTIONS = ("fit_on", "bounds", "start")
# smallest allowed value of each numeric option (integers where the default is one)
OPTION_MINIMUM = {"n_candidates": 0, "inertia_end": 0.0, "inertia_start": 0.0, "c1": 0.0, "c2": 0.0}


def list_methods() -> list[str]:
    return list(METHODS) + ["auto"]


def applicable_methods(model: HysteresisModel | str) -> list[str]:
    """The methods of ``METHODS`` that can identify this model."""
    model = get_model(model) if isinstance(model, str) else model
    if model.n_params == 0:
        return []
    if model.has_linear_part:
        return list(METHODS)
    return [m for m in METHODS if "varpro" not in m.split("+")]


def resolve_method(method: str, model: HysteresisModel) -> list[str]:
    """Stage names of a method, checked against the model."""
    if not isinstance(method, str) or not method:
        raise IdentificationError(f"method must be a name, got {method!r}")
    if method == "auto":
        method = "varpro" if model.has_linear_part else "lsq"
    stages = method.split("+")
    unknown = [s for s in stages if s not in STAGES]
    if unknown:
        raise IdentificationError(
            f"unknown method {method!r} for model {model.name!r}; methods: {', '.join(list_methods())}"
        )
    if "varpro" in stages and not model.has_linear_part:
        raise IdentificationError(
            f"method {method!r} cannot identify model {model.name!r}: it has no linear parameters to solve "
            "exactly (use 'lsq' or 'mpso')"
        )
    if model.n_params == 0:
        raise IdentificationError(f"model {model.name!r} has no parameters to identify (method {method!r})")
    return stages


def _check_value(key: str, value, default):
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise IdentificationError(f"option {key} must be true or false, got {value!r}")
        return value
    minimum = OPTION_MINIMUM.get(key, 1 if isinstance(default, int) else None)
    if isinstance(default, int):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
            raise IdentificationError(f"option {key} must be an integer >= {minimum}, got {value!r}")
        return int(value)
    if isinstance(value, bool) or not isinstance(value, (int, float, np.number)) or not math.isfinite(value):
        raise IdentificationError(f"option {key} must be a finite number, got {value!r}")
    if (minimum is None and value <= 0) or (minimum is not None and value < minimum):
        raise IdentificationError(f"option {key} must be {'positive' if minimum is None else f'>= {minimum}'}, "
                                  f"got {value!r}")
    return float(value)


def split_options(stages: list[str], method: str, options: Mapping) -> tuple[dict, list[dict]]:
    """Common options and the resolved options of each stage (defaults filled in)."""
    common = {k: options[k] for k in COMMON_OPTIONS if k in options}
    per_stage = [dict(STAGES[s].OPTIONS) for s in stages]
    for key, value in options.items():
        if key in COMMON_OPTIONS:
            continue
        stage, _, name = key.rpartition(".")
        targets = [i for i, s in enumerate(stages) if (not stage or s == stage) and name in STAGES[s].OPTIONS]
        if not targets:
            known = sorted({f"{s}.{k}" if len(stages) > 1 else k for s in stages for k in STAGES[s].OPTIONS})
            raise IdentificationError(
                f"unknown option {key!r} for method {method!r}; options: {', '.join(list(COMMON_OPTIONS) + known)}"
            )
        for i in targets:
            per_stage[i][name] = _check_value(key, value, STAGES[stages[i]].OPTIONS[name])
    for s, opts in zip(stages, per_stage):
        if s == "mpso" and opts["inertia_end"] > opts["inertia_start"]:
            raise IdentificationError("option inertia_end must not exceed inertia_start")
    return common, per_stage


def _fit_records(dataset: Dataset, fit_on, model_name: str, method: str):
    if fit_on is None:
        chosen = dataset.identification
        if not chosen:
            raise IdentificationError(
                f"dataset {dataset.name!r} has no identification records: method {method!r} cannot fit model "
                f"{model_name!r} (mark records role = \"identification\", or pass fit_on)"
            )
        return chosen
    if isinstance(fit_on, str) or not all(isinstance(f, str) for f in fit_on):
        raise IdentificationError(f"option fit_on must be a list of record file names, got {fit_on!r}")
    files = [r.file for r in dataset.records]
    unknown = [f for f in fit_on if f not in files]
    if unknown:
        raise IdentificationError(
            f"fit_on: dataset {dataset.name!r} has no record(s) {', '.join(unknown)} (records: {', '.join(files)})")
    if not fit_on:
        raise IdentificationError(f"fit_on is empty: nothing to fit model {model_name!r} on")
    return [r for r in dataset.records if r.file in set(fit_on)]


def _at_bounds(problem: Problem, x: np.ndarray, rel: float = 1e-6) -> list[tuple[str, str, float]]:
    """(name, "lower"/"upper", bound) of the parameters within 1e-6 of the width from a finite bound
    (trust-region methods stop just inside)."""
    out = []
    width = np.where(np.isfinite(problem.upper - problem.lower), problem.upper - problem.lower, 1.0)
    for i, name in enumerate(problem.names):
        lo, hi = problem.lower[i], problem.upper[i]
        if not hi > lo:
            continue  # fixed by the user
        if np.isfinite(lo) and x[i] - lo <= rel * width[i]:
            out.append((name, "lower", float(lo)))
        elif np.isfinite(hi) and hi - x[i] <= rel * width[i]:
            out.append((name, "upper", float(hi)))
    return out


_HASHES: dict[int, tuple] = {}


def dataset_hash(dataset: Dataset) -> str:
    """``dataset.content_hash()``, remembered per Dataset object while its records
    stay the same objects (the ablation and the matrix fit one dataset many times)."""
    key = tuple((id(r), id(r.u), id(r.y), r.file, r.role, r.weight, r.start, r.stop) for r in dataset.records)
    held = _HASHES.get(id(dataset))
    if held is not None and held[0]() is dataset and held[1] == key:
        return held[2]
    value = dataset.content_hash()
    if len(_HASHES) > 64:
        _HASHES.clear()
    _HASHES[id(dataset)] = (weakref.ref(dataset), key, value)
    return value


def _version() -> str:
    try:
        return metadata.version("hysbench")
    except metadata.PackageNotFoundError:
        return ""


def identify(model: HysteresisModel | str, dataset: Dataset | str | os.PathLike, method: str = "auto",
             seed: int | None = 0, **options) -> Fit:
    """Identify ``model`` on ``dataset``'s identification records; see the module docstring."""
    if isinstance(model, str):
        model = get_model(model)
    elif not isinstance(model, HysteresisModel):
        raise IdentificationError(f"model must be a registry name or a HysteresisModel, got {type(model).__name__}")
    if isinstance(dataset, (str, os.PathLike)):
        dataset = load_dataset(dataset)
    elif not isinstance(dataset, Dataset):
        raise IdentificationError(f"dataset must be a Dataset or a folder, got {type(dataset).__name__}")
    if seed is not None and (isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0):
        raise IdentificationError(f"seed must be a non-negative integer, got {seed!r}")
    stages = resolve_method(method, model)
    name = "+".join(stages)
    common, per_stage = split_options(stages, name, options)
    records = _fit_records(dataset, common.get("fit_on"), model.name, name)
    bounds = common.get("bounds")
    if bounds is not None and not isinstance(bounds, Mapping):
        raise IdentificationError(f"option bounds must map parameter names to [low, high], got {bounds!r}")
    start = common.get("start")
    if start is not None and not (isinstance(start, Mapping) and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in start.values())):
        raise IdentificationError(f"option start must map parameter names to finite numbers, got {start!r}")
    problem = Problem.build(model, records, bounds)
    if "mpso" in stages and not (np.all(np.isfinite(problem.lower)) and np.all(np.isfinite(problem.upper))):
        raise IdentificationError(f"method 'mpso' needs finite bounds for every parameter of model {model.name!r}")
    problem.start_vector(start)  # checks names early

    t0 = time.perf_counter()
    diagnostics, notes, x = {}, [], None
    for stage, opts in zip(stages, per_stage):
        with threadpool_limits(1, user_api="blas"):  # small dense algebra: threads only contend
            kwargs = {"x0": x} if (stage == "lsq" and x is not None) else {}
            stage_start = start if x is None else model.unpack(x)
            out = STAGES[stage].run(problem, seed, stage_start, **kwargs, **opts)
        x = out["x"]
        diagnostics[stage] = {**out["diagnostics"], "n_evaluations_total": problem.n_evaluations}
        notes += out["notes"]
    fit_seconds = time.perf_counter() - t0

    params = model.unpack(problem.clip(x))
    at_bounds = _at_bounds(problem, model.pack(params))
    if at_bounds:
        notes.append("parameters at their bounds: " + ", ".join(f"{n} ({side} {v:.4g})" for n, side, v in at_bounds)
                     + "; the optimum may lie beyond (option bounds widens them)")
    diagnostics["at_bounds"] = [n for n, _, _ in at_bounds]
    n_nonfinite = problem.n_nonfinite
    if n_nonfinite:
        notes.append(f"{n_nonfinite} of {problem.n_evaluations} evaluated parameter sets gave non-finite model "
                     "output (treated as an infinite fitness during the search)")
    residual = problem.residuals_batch(problem.vector(params)[None])[0]
    problem.n_evaluations -= 1  # the final scoring is not part of the search
    finite = bool(np.all(np.isfinite(residual)))
    fitness = float(residual @ residual) if finite else math.nan
    if finite:
        success, message = True, f"identified with {name} in {problem.n_evaluations} evaluations"
    else:
        success, message = False, "the model's output is not finite at the identified parameters"
        notes.append(message + ": the fit is not scored")
    n_rows = problem.n_rows
    k = sum(1 for lo, hi in zip(problem.lower, problem.upper) if hi > lo)
    fitted = {r.file for r in records}
    scores = score_records(model, params, dataset.records, problem.input_range)
    scores = [type(s)(s.file, s.frequency_hz, "identification" if s.file in fitted else "validation", s.e_m, s.e_rms)
              for s in scores]
    names = model.param_names
    return Fit(
        model=model.name,
        hyperparameters=model.get_hyperparameters(),
        method=name,
        params=params,
        fitness=fitness,
        records=scores,
        n_evaluations=problem.n_evaluations,
        fit_seconds=fit_seconds,
        history=list(problem.history),
        input_range=problem.input_range,
        bounds={n: (float(problem.lower[i]), float(problem.upper[i])) for i, n in enumerate(names)},
        scale={"u": problem.scale.u, "y": problem.scale.y, "time": problem.scale.time},
        options={**{k: v for k, v in common.items()}, **{s: o for s, o in zip(stages, per_stage)}},
        seed=None if seed is None else int(seed),
        dataset=dataset.name,
        dataset_hash=dataset_hash(dataset),
        fitted_on=[r.file for r in records],
        diagnostics=diagnostics,
        notes=notes,
        version=_version(),
        success=success,
        message=message,
        n_nonfinite=n_nonfinite,
        n_rows=n_rows,
        aic=aic(fitness, n_rows, k) if finite else math.nan,
        bic=bic(fitness, n_rows, k) if finite else math.nan,
        _instance=model,
    )
