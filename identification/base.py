"""Identifiers as strategy objects (in the manner of pysindy's optimizers and scikit-learn estimators).

An ``Identifier`` holds its options as constructor arguments (``get_params``) and
knows models only through the model interface. ``search(problem, seed, start,
x0)`` is the algorithm: it minimises eq. 9 over a prepared ``Problem`` and
returns the parameter vector, diagnostics and notes. ``fit(model, dataset,
seed, fit_on=, bounds=, start=)`` is the same for every identifier: it builds
the problem from the dataset's identification records, runs ``search``, and
returns the one result type, ``Fit`` (scores on every record, parameters at
their bounds, non-finite evaluations, AIC/BIC). ``Chain(A, B)`` runs B from
A's result. ``identify()`` (api.py) builds an identifier from a method name
and KEY=VALUE options.
"""

from __future__ import annotations

import inspect
import math
import time
import weakref
from abc import ABC, abstractmethod
from importlib import metadata
from typing import ClassVar, Mapping

import numpy as np
from threadpoolctl import threadpool_limits

from hysbench.data.dataset import Dataset
from hysbench.data.protocol import score_records
from hysbench.models.base import HysteresisModel

from .criteria import aic, bic
from .errors import IdentificationError
from .fit import Fit, squared_unit
from .problem import Problem


# smallest allowed value of each numeric option (integers where the default is one)
OPTION_MINIMUM = {"n_candidates": 0, "inertia_end": 0.0, "inertia_start": 0.0, "c1": 0.0, "c2": 0.0}


def check_option(key: str, value, default):
    """``value`` checked against the kind of its default (bool, integer >= its minimum, positive or
    bounded finite number; a default of None also takes None), as a plain bool, int or float."""
    if default is None and value is None:
        return None
    if isinstance(default, bool):
        if not isinstance(value, (bool, np.bool_)):
            raise IdentificationError(f"option {key} must be true or false, got {value!r}")
        return bool(value)
    minimum = OPTION_MINIMUM.get(key, 1 if isinstance(default, int) else None)
    if isinstance(default, int):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)) or value < minimum:
            raise IdentificationError(f"option {key} must be an integer >= {minimum}, got {value!r}")
        return int(value)
    if (isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number))
            or not math.isfinite(value)):
        raise IdentificationError(f"option {key} must be a finite number, got {value!r}")
    if (minimum is None and value <= 0) or (minimum is not None and value < minimum):
        raise IdentificationError(f"option {key} must be {'positive' if minimum is None else f'>= {minimum}'}, "
                                  f"got {value!r}")
    return float(value)


class Identifier(ABC):
    """Base class: options are the constructor's arguments; ``search`` is the algorithm.

    The constructor stores its arguments as given (``get_params``, ``repr``); ``fit`` checks them
    with the rules ``identify`` applies to the same options (``check_options``) and never changes them.
    """

    name: ClassVar[str] = ""

    def get_params(self) -> dict:
        """The constructor arguments, as given (scikit-learn's get_params)."""
        names = [p for p in inspect.signature(type(self).__init__).parameters if p != "self"]
        return {n: getattr(self, n) for n in names}

    def check_options(self) -> None:
        """Refuse, in one line, an option of the wrong kind or out of range (as ``identify`` does)."""
        defaults = {n: p.default for n, p in inspect.signature(type(self).__init__).parameters.items() if n != "self"}
        for key, value in self.get_params().items():
            check_option(key, value, defaults[key])

    def __repr__(self) -> str:
        return f"{type(self).__name__}({', '.join(f'{k}={v!r}' for k, v in self.get_params().items())})"

    @property
    def method(self) -> str:
        return "+".join(s.name for s in self.stages())

    def stages(self) -> list["Identifier"]:
        return [self]

    def check(self, model: HysteresisModel, problem: Problem | None = None) -> None:
        """Refuse a model (or its bounds) this identifier cannot work with, in one line."""

    @abstractmethod
    def search(self, problem: Problem, seed: int | None, start: Mapping[str, float] | None,
               x0: np.ndarray | None = None) -> dict:
        """{"x": parameter vector, "diagnostics": dict, "notes": [str]} minimising eq. 9 on ``problem``."""

    def run_stages(self, problem: Problem, seed, start) -> tuple[np.ndarray, dict, list]:
        diagnostics, notes, x = {}, [], None
        for stage in self.stages():
            with threadpool_limits(1, user_api="blas"):  # small dense algebra: threads only contend
                stage_start = start if x is None else problem.model.unpack(x)
                out = stage.search(problem, seed, stage_start, x0=x)
            x = out["x"]
            diagnostics[stage.name] = {**out["diagnostics"], "n_evaluations_total": problem.n_evaluations}
            notes += out["notes"]
        return x, diagnostics, notes

    def fit(self, model: HysteresisModel, dataset: Dataset, seed: int | None = 0, *, fit_on=None,
            bounds: Mapping | None = None, start: Mapping | None = None) -> Fit:
        """Identify ``model`` on the dataset's identification records (or ``fit_on``)."""
        name = self.method
        for stage in self.stages():
            stage.check_options()
            stage.check(model)
        common = {k: v for k, v in (("fit_on", fit_on), ("bounds", bounds), ("start", start)) if v is not None}
        records = _fit_records(dataset, fit_on, model.name, name)
        if bounds is not None and not isinstance(bounds, Mapping):
            raise IdentificationError(f"option bounds must map parameter names to [low, high], got {bounds!r}")
        if start is not None and not (isinstance(start, Mapping) and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in start.values())):
            raise IdentificationError(f"option start must map parameter names to finite numbers, got {start!r}")
        problem = Problem.build(model, records, bounds, others=[r for r in dataset.records if all(r is not f for f in records)])
        for stage in self.stages():
            stage.check(model, problem)
        problem.start_vector(start)  # checks names early

        t0 = time.perf_counter()
        x, diagnostics, notes = self.run_stages(problem, seed, start)
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
        scaled_fitness = float(residual @ residual) if finite else math.nan
        fitness = scaled_fitness * problem.output_scale**2
        if fitness == 0.0 < scaled_fitness or math.isinf(fitness) and math.isfinite(scaled_fitness):
            notes.append(f"fitness (eq. 9) is {scaled_fitness:.6g} x 2^{2 * math.frexp(problem.output_scale)[1] - 2} "
                         f"{squared_unit(dataset.output_unit or '') or 'in the output unit squared'}, beyond the range "
                         "of a float: shown as "
                         f"{fitness:g}; e_m and e_rms are exact")
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
            options={**common, **{s.name: s.get_params() for s in self.stages()}},
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
            undetermined=[str(n) for n in diagnostics[self.stages()[-1].name].get("undetermined", {})],
            output_unit=dataset.output_unit or "",
            input_unit=dataset.input_unit or "",
            _instance=model,
        )


class Chain(Identifier):
    """Stages run in turn, each from the previous one's result (``varpro+lsq`` polishes varpro's optimum)."""

    def __init__(self, *stages: Identifier):
        if len(stages) < 2:
            raise IdentificationError("a chain needs at least two identifiers")
        for stage, after in zip(stages, stages[1:]):
            if getattr(stage, "stable_inverse", False):  # the next stage would move the parameters unconstrained
                raise IdentificationError(
                    f"option stable_inverse: stage {after.name!r} after {stage.name!r} would move the parameters "
                    f"without the constraint; use {stage.name!r} alone (or last)")
        self._stages = list(stages)

    def get_params(self) -> dict:
        """{stage name: that stage's get_params()}."""
        return {s.name: s.get_params() for s in self._stages}

    def __repr__(self) -> str:
        return f"Chain({', '.join(repr(s) for s in self._stages)})"

    def stages(self) -> list[Identifier]:
        return list(self._stages)

    def search(self, problem, seed, start, x0=None) -> dict:
        x, diagnostics, notes = self.run_stages(problem, seed, start)
        return {"x": x, "diagnostics": diagnostics, "notes": notes}


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


