"""Identifiers behind one call: ``identify(model, dataset, method, seed, **options) -> Fit``.

Methods: ``varpro`` (separable least squares), ``mpso`` (the paper's modified
particle swarm), ``lsq`` (nonlinear least squares), their chains
``varpro+lsq`` and ``mpso+lsq``, and ``auto``. See ``api`` and each method's
module for what they do and their defaults.
"""

from .api import METHODS, applicable_methods, identify, list_methods
from .errors import IdentificationError
from .fit import Fit
from .problem import Problem, data_scale
from .varpro import LinearSolution, SeparableProblem

__all__ = [
    "METHODS",
    "Fit",
    "IdentificationError",
    "LinearSolution",
    "Problem",
    "SeparableProblem",
    "applicable_methods",
    "data_scale",
    "identify",
    "list_methods",
]
