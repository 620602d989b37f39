"""``native``: a model trained by its own library (the black-box learners of models/black_box.py).

Such a model declares ``native_training`` and a ``train(records, sample_time, seed,
simulation_error)`` method; this identifier hands it each fit record's own stretch
(u, y, dt, the scored window within it; ``data.segments.own_stretch``): the record, run-in included,
up to any other record's scored window of the same recording (a recording split into an
identification and a validation window: the validation window's output is never read), the
model step fixed for this fit (``sample_time``, from the model's start from the data) and a
callable giving eq. 9 of a candidate parameter set in free-run simulation of those records
(counted as evaluations, as every identifier's are). The result is the usual ``Fit``: scored
on every record, saved and reloaded, by the same harness as every other model.
"""

from __future__ import annotations

import math

import numpy as np

from .base import Identifier
from .errors import IdentificationError
from .problem import Problem


def is_native(model) -> bool:
    """Whether a model is trained by its own library rather than by a parameter search."""
    return bool(getattr(model, "native_training", False))


class Native(Identifier):
    """Calls the model's own training; see the module docstring."""

    name = "native"

    def __init__(self):
        pass

    def check(self, model, problem: Problem | None = None) -> None:
        if not is_native(model):
            raise IdentificationError(f"method 'native' trains only models that carry their own training; model "
                                      f"{model.name!r} is identified by a parameter search (varpro, lsq, mpso)")

    def search(self, problem: Problem, seed, start, x0=None) -> dict:
        model = problem.model
        sample_time = problem.start_vector(None)[model.param_names.index("sample_time")]

        def simulation_error(params) -> float:
            return float(problem.fitness_batch(model.pack(params)[None])[0])

        stretches = problem.stretches or [slice(0, r.t.size) for r in problem.records]
        records = [(r.u[s], r.y[s], r.dt, slice(r.start - s.start, r.stop - s.start))
                   for r, s in zip(problem.records, stretches)]
        params, diagnostics, notes = model.train(records, float(sample_time), seed, simulation_error)
        x = model.pack(params)
        if not np.all(np.isfinite(x)):
            raise IdentificationError(f"model {model.name!r}: training gave non-finite weights")
        if math.isinf(problem.best_fitness) and not problem.history:
            problem.note(simulation_error(params))
        return {"x": x, "diagnostics": {**diagnostics, "sample_time": float(sample_time)}, "notes": notes}


OPTIONS: dict = {}
