"""``identify(model, dataset, method, seed, **options) -> Fit``: every identifier behind one call.

Methods (see each module's docstring):

* ``varpro`` -- separable least squares: exact solve of the linear
  parameters, multi-start search over the nonlinear ones. Needs a model with
  a linear part; a model with no nonlinear parameter is one linear solve.
* ``mpso`` -- modified particle swarm over all parameters (the paper's).
* ``lsq`` -- scipy.optimize.least_squares over all parameters.
* chains ``A+B`` run B from A's result; ``varpro+lsq`` and ``mpso+lsq`` are
  the polished forms (lsq starts exactly at the previous stage's parameters).
* ``native`` -- the model's own training (the black-box learners, trained by their
  library: see native.py); the only method for such models.
* ``auto`` -- ``native`` for a model trained by its own library, ``varpro`` for a model
  with a linear part, else ``lsq``.

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

import os
from typing import Mapping

import numpy as np

from hysbench.data.dataset import Dataset, fitting_problems, load_dataset
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel

from . import lsq, mpso, native, varpro
from .base import Chain, Identifier, check_option
from .errors import IdentificationError
from .fit import Fit
from .lsq import LeastSquares
from .mpso import ParticleSwarm
from .native import Native, is_native
from .varpro import Varpro

STAGES = {"varpro": varpro, "mpso": mpso, "lsq": lsq, "native": native}
IDENTIFIERS = {"varpro": Varpro, "mpso": ParticleSwarm, "lsq": LeastSquares, "native": Native}
METHODS = ("varpro", "mpso", "lsq", "varpro+lsq", "mpso+lsq")  # the parameter searches
NATIVE = "native"  # a model's own training (the black-box learners); the only method for them
COMMON_OPTIONS = ("fit_on", "bounds", "start")


def list_methods() -> list[str]:
    return list(METHODS) + [NATIVE, "auto"]


def applicable_methods(model: HysteresisModel | str) -> list[str]:
    """The methods that can identify this model: ``METHODS`` that apply, or ``native`` alone."""
    model = get_model(model) if isinstance(model, str) else model
    if is_native(model):
        return [NATIVE]
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
        method = "native" if is_native(model) else ("varpro" if model.has_linear_part else "lsq")
    stages = method.split("+")
    unknown = [s for s in stages if s not in STAGES]
    if unknown:
        raise IdentificationError(
            f"unknown method {method!r} for model {model.name!r}; methods: {', '.join(list_methods())}"
        )
    if is_native(model) and stages != ["native"]:
        raise IdentificationError(f"model {model.name!r} is trained by its own library: use method 'native' "
                                  f"(not {method!r})")
    if "native" in stages and (len(stages) > 1 or not is_native(model)):
        raise IdentificationError(f"method {method!r} cannot identify model {model.name!r}: 'native' trains only "
                                  "the black-box models, alone")
    if "varpro" in stages and not model.has_linear_part:
        raise IdentificationError(
            f"method {method!r} cannot identify model {model.name!r}: it has no linear parameters to solve "
            "exactly (use 'lsq' or 'mpso')"
        )
    if model.n_params == 0:
        raise IdentificationError(f"model {model.name!r} has no parameters to identify (method {method!r})")
    return stages


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
            per_stage[i][name] = check_option(key, value, STAGES[stages[i]].OPTIONS[name])
    for s, opts in zip(stages, per_stage):
        if s == "mpso":
            IDENTIFIERS[s](**opts).check(None)  # the swarm's own consistency (inertia)
    return common, per_stage


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
    if options.get("fit_on") is None and dataset.identification:  # (none at all: the identifier names the method)
        for problem in fitting_problems(dataset):  # fitted on the identification records: they must vary
            raise IdentificationError(f"dataset {dataset.name!r}: {problem}")
    identifier = build_identifier(method, model, options)
    common = {k: options[k] for k in COMMON_OPTIONS if k in options}
    return identifier.fit(model, dataset, seed, **common)


def build_identifier(method: str, model: HysteresisModel, options: Mapping | None = None) -> Identifier:
    """The identifier a method name and KEY=VALUE options describe (options checked, defaults filled)."""
    stages = resolve_method(method, model)
    _, per_stage = split_options(stages, "+".join(stages), options or {})
    built = [IDENTIFIERS[s](**opts) for s, opts in zip(stages, per_stage)]
    return built[0] if len(built) == 1 else Chain(*built)
