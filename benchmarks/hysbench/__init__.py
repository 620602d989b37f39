"""hysbench: the benchmark suite for rate-dependent hysteresis models, as a Python API.

``import hysbench as hb`` gives the handful of names a user needs::

    import hysbench as hb

    ds = hb.load_dataset()                    # the shipped virtual DEA (or a folder holding dataset.toml)
    print(hb.list_models())                   # registry names
    fit = hb.identify("mrpim", ds, method="varpro", seed=0)
    for score in fit.records:                 # e_m and e_rms (%) per record, as in the paper
        print(score.file, score.role, round(score.e_rms, 2))

The names are defined in ``hysbench.benchmarks.api`` and loaded on first use (PEP 562), so
importing one layer (``hysbench.models``, which runs this file first as its parent package) stays
cheap. Everything else lives in the four layers: ``hysbench.models``, ``hysbench.data``,
``hysbench.identification`` and ``hysbench.benchmarks``.

This file is installed as the package ``hysbench`` (``package-dir`` in pyproject.toml).
"""

from importlib import import_module
from importlib.metadata import PackageNotFoundError, version

API = ("load_dataset", "get_model", "list_models", "identify", "run_matrix", "diagnose", "load_model")
__all__ = ["__version__", *API]

try:
    __version__ = version("hysbench")
except PackageNotFoundError:  # a source tree that is not installed
    __version__ = "0+unknown"


def __getattr__(name: str):
    if name in API:
        return getattr(import_module("hysbench.benchmarks.api"), name)
    raise AttributeError(f"module 'hysbench' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *API])
