"""Identifiers behind one call: ``identify(model, dataset, method, seed, **options) -> Fit``.

Methods: ``varpro`` (separable least squares), ``mpso`` (hysbench's modified
particle swarm, in the paper's spirit), ``lsq`` (nonlinear least squares), their
chains ``varpro+lsq`` and ``mpso+lsq``, and ``auto``. Each is a strategy object
(``Varpro``, ``ParticleSwarm``, ``LeastSquares``, ``Chain``; base class
``Identifier`` in base.py) with its options as constructor arguments:
``Varpro(n_starts=4).fit(model, dataset, seed)`` is ``identify(model, dataset,
"varpro", seed, n_starts=4)``.
"""

import hysbench.models  # noqa: F401  (first: numba's cache folder, see models/numba_cache.py)

from .api import IDENTIFIERS, METHODS, applicable_methods, build_identifier, identify, list_methods
from .base import Chain, Identifier
from .errors import IdentificationError
from .fit import Fit
from .problem import Problem, data_scale
from .lsq import LeastSquares
from .mpso import ParticleSwarm
from .varpro import LinearSolution, SeparableProblem, Varpro

__all__ = [
    "Chain",
    "IDENTIFIERS",
    "Identifier",
    "LeastSquares",
    "ParticleSwarm",
    "Varpro",
    "build_identifier",
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
