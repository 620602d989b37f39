"""``native``: a model trained by its own library (the black-box learners of models/black_box.py).

Such a model declares ``native_training`` and a ``train(records, sample_time, seed,
simulation_error)`` method; this identifier hands it the scored windows of the fit records
(u, y, dt, the whole slice): the samples eq. 9 covers, the only outputs any other identifier
fits (a record's output outside its window may be another record's validation window, as
when one recording is split into an identification and a validation window), the
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

        # the scored windows only: a learner sees the outputs every other identifier fits, no more
        records = [(r.u[r.scored], r.y[r.scored], r.dt, slice(None)) for r in problem.records]
        params, diagnostics, notes = model.train(records, float(sample_time), seed, simulation_error)
        x = model.pack(params)
        if not np.all(np.isfinite(x)):
            raise IdentificationError(f"model {model.name!r}: training gave non-finite weights")
        if math.isinf(problem.best_fitness) and not problem.history:
            problem.note(simulation_error(params))
        return {"x": x, "diagnostics": {**diagnostics, "sample_time": float(sample_time)}, "notes": notes}


OPTIONS: dict = {}
