"""One cell of the matrix: identify a model with one method on one dataset, then score it."""

from __future__ import annotations

import functools
import hashlib
import json
import time
import traceback
from dataclasses import asdict, dataclass, field
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import numpy as np

import hysbench.data
import hysbench.identification
import hysbench.models
from hysbench.data.dataset import Dataset, load_dataset
from hysbench.identification import METHODS, applicable_methods as identifier_methods, identify
from hysbench.identification.api import NATIVE, resolve_method, split_options
from hysbench.models import get_model, list_models
from hysbench.models.errors import HysbenchError

CELL_FORMAT = "hysbench-cell/2"


def package_version() -> str:
    try:
        return version("hysbench")
    except PackageNotFoundError:  # running from a source tree
        return "0+unknown"


def source_fingerprint(packages, files=()) -> str:
    """SHA-256 (16 hex digits) over the Python source of ``packages`` (their folders, recursively) and ``files``."""
    digest = hashlib.sha256()
    folders = [Path(p) for pkg in packages for p in pkg.__path__]
    for f in sorted({f for folder in folders for f in folder.rglob("*.py")} | {Path(f) for f in files}):
        digest.update(f.name.encode())
        digest.update(f.read_bytes())
    return digest.hexdigest()[:16]


@functools.lru_cache(maxsize=1)
def code_fingerprint() -> str:
    """The source of everything a cell's result depends on: the models, the data layer, the identifiers and
    this module (not the reports, the CLI or the figures). A cell computed by other code gets another key, so
    ``hysbench run`` never reuses it."""
    return source_fingerprint((hysbench.models, hysbench.data, hysbench.identification), (__file__,))


@dataclass(frozen=True)
class Cell:
    """What a cell computes; everything that can change its result is in ``key``."""

    dataset_path: str
    dataset_name: str
    dataset_hash: str
    model: str
    method: str
    seed: int
    options: tuple = ()  # sorted (name, value) pairs for the identifier
    hyperparameters: str = "{}"  # the model's constructor arguments, as sorted JSON

    @property
    def name(self) -> str:
        return f"{self.dataset_name}/{self.model}/{self.method}"

    @property
    def key(self) -> str:
        ident = {
            "dataset": self.dataset_hash,
            "model": self.model,
            "method": self.method,
            "seed": self.seed,
            "options": [list(o) for o in self.options],
            "hyperparameters": self.hyperparameters,
            "code": code_fingerprint(),
        }
        return hashlib.sha256(json.dumps(ident, sort_keys=True).encode()).hexdigest()[:20]


@dataclass
class CellResult:
    """One cell of the matrix: a model identified by one method on one dataset, scored on every record.
    ``hb.run_matrix`` returns these as dicts (``to_dict``), one key per attribute.

    Attributes
    ----------
    key : str
        The cell's key (``Cell.key``): a hash of everything that can change its result.
    dataset : str
        The dataset's name.
    model : str
        The model's registry name.
    method : str
        The identifier.
    seed : int
        The seed of the identification.
    options : dict
        The identifier options the cell ran with (the matrix's budget and the user's).
    status : str
        "ok" or "failed".
    n_params : int
        The model's number of parameters.
    fitness : float
        Eq. 9 on the fit records, in the output unit squared (NaN: failed).
    fit_seconds : float
        Wall time of the identification, s.
    simulate_seconds : float
        Wall time of simulating every record once with the fitted parameters, s.
    n_evaluations : int
        Model evaluations of the search.
    params : dict
        The identified parameters, name -> value.
    input_range : list
        [min, max] of the input over the fit records.
    records : list[dict]
        Per record: ``file``, ``frequency_hz``, ``role``, ``e_m`` and ``e_rms`` (percent of the measured
        peak-to-peak of the scored window, eq. 10).
    error : str
        Why the cell failed ("" when it did not).
    nonfinite_records : list
        Records whose prediction is not finite.
    fit : dict
        The Fit itself (``Fit.to_dict()``; empty when the cell failed).
    format : str
        The cell file's format tag.
    """

    key: str
    dataset: str
    model: str
    method: str
    seed: int
    options: dict
    status: str
    n_params: int = 0
    fitness: float = float("nan")
    fit_seconds: float = float("nan")
    simulate_seconds: float = float("nan")
    n_evaluations: int = 0
    params: dict = field(default_factory=dict)
    input_range: list = field(default_factory=list)
    records: list = field(default_factory=list)
    error: str = ""
    nonfinite_records: list = field(default_factory=list)
    fit: dict = field(default_factory=dict)
    format: str = CELL_FORMAT

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "CellResult":
        return cls(**d)


# The default matrix runs the three identifiers, and "native" (the only method of the black-box learners,
# which train with their own library); chains such as varpro+lsq are run when named.
DEFAULT_METHODS = ("varpro", "mpso", "lsq", "native")

# The matrix's default budget per cell, so that every model x identifier on the virtual DEA fits in
# well under five minutes on two cores: mpso gets 400 model evaluations (20 particles x 20 iterations),
# lsq 20 residual evaluations plus their batched Jacobians, varpro one local search from the best of 8
# candidates. ``--full-budget`` runs the identifiers' own defaults instead.
MATRIX_BUDGET = {
    "varpro": {"n_candidates": 8, "n_starts": 1},
    "mpso": {"swarm_size": 20, "iterations": 19},
    "lsq": {"max_nfev": 20},
}


def method_options(methods: list[str] | None, user: dict, full_budget: bool) -> dict:
    """Options per method: the matrix budget (unless ``full_budget``) overridden by the user's."""
    out = {}
    for method in methods or DEFAULT_METHODS:
        chain = "+" in method  # a chain's stages take prefixed options
        base = {} if full_budget else {(f"{stage}.{k}" if chain else k): v for stage in method.split("+")
                                       for k, v in MATRIX_BUDGET.get(stage, {}).items()}
        merged = {**base, **user.get(method, {})}
        if merged:
            out[method] = merged
    for method in user:
        out.setdefault(method, user[method])
    return out


def applicable_methods(model_name: str) -> list[str]:
    """Identifiers that apply to a model, through the interface only."""
    return identifier_methods(model_name)


def hyperparameters_key(model_name: str) -> str:
    return json.dumps(get_model(model_name).get_hyperparameters(), sort_keys=True, default=str)


def plan_cells(datasets: list[tuple[str, Dataset]], models: list[str] | None, methods: list[str] | None,
               seed: int, method_options: dict | None = None) -> list[Cell]:
    """Every requested model x applicable method x dataset (unknown names raise HysbenchError)."""
    known_methods = list(METHODS) + [NATIVE]
    models = models or list_models(matrix_only=True)
    for m in models:
        get_model(m)  # raises on an unknown name
    for m in methods or []:
        if m not in known_methods:
            raise HysbenchError(f"unknown method {m!r}; known methods: {', '.join(known_methods)}")
    method_options = method_options or {}
    _check_options(models, methods, method_options)
    cells = []
    for path, ds in datasets:
        digest = ds.content_hash()
        for model in models:
            for method in applicable_methods(model):
                if method not in (methods or DEFAULT_METHODS):
                    continue
                opts = tuple(sorted(method_options.get(method, {}).items()))
                cells.append(Cell(str(path), ds.name, digest, model, method, seed, opts, hyperparameters_key(model)))
    return cells


def _check_options(models, methods, method_options) -> None:
    """Refuse unknown or bad identifier options before anything runs."""
    for method, opts in method_options.items():
        if method not in (methods or DEFAULT_METHODS):
            raise HysbenchError(f"--option names method {method!r}, which is not being run")
        for model in models:
            if method in applicable_methods(model):
                stages = resolve_method(method, get_model(model))
                split_options(stages, method, opts)
                break


_DATASET_CACHE: dict[str, Dataset] = {}


def _dataset(cell: Cell) -> Dataset:
    ds = _DATASET_CACHE.get(cell.dataset_path)
    if ds is None or ds.content_hash() != cell.dataset_hash:
        ds = load_dataset(cell.dataset_path)
        _DATASET_CACHE.clear()
        _DATASET_CACHE[cell.dataset_path] = ds
    return ds


def run_cell(cell: Cell) -> dict:
    """Identify and score; returns CellResult.to_dict(). Never raises for a failed fit.

    A model whose prediction of a record is not finite is reported (status "nonfinite", the
    records named), never scored as a bad fit."""
    base = dict(key=cell.key, dataset=cell.dataset_name, model=cell.model, method=cell.method, seed=cell.seed,
                options=dict(cell.options))
    try:
        ds = _dataset(cell)
        model = get_model(cell.model)
        fit = identify(model, ds, method=cell.method, seed=cell.seed, **dict(cell.options))
        t0 = time.perf_counter()
        nonfinite = [r.file for r in ds.records if not np.all(np.isfinite(fit.simulate(r.u, r.dt)))]
        simulate_seconds = time.perf_counter() - t0
        if not fit.success:  # the Fit's own flag: output not finite at the identified parameters
            nonfinite = nonfinite or list(fit.fitted_on)
        status = "nonfinite" if nonfinite else "ok"
        error = f"non-finite model output on {', '.join(nonfinite)}" if nonfinite else ""
        return CellResult(
            **base, status=status, error=error, nonfinite_records=nonfinite, fit=fit.to_dict(), n_params=model.n_params, fitness=float(fit.fitness),
            fit_seconds=float(fit.fit_seconds), simulate_seconds=simulate_seconds,
            n_evaluations=int(fit.n_evaluations), params=dict(fit.params),
            input_range=[float(x) for x in fit.input_range],
            records=[_record_dict(s) for s in fit.records],
        ).to_dict()
    except Exception as exc:  # a failed cell is reported, not fatal to the run
        detail = "".join(traceback.format_exception_only(type(exc), exc)).strip().splitlines()[-1]
        return CellResult(**base, status="failed", error=detail).to_dict()


def _record_dict(score) -> dict:
    d = score if isinstance(score, dict) else score.as_dict()
    return {k: d[k] for k in ("file", "frequency_hz", "role", "e_m", "e_rms")}


def dataset_path_label(path: str) -> str:
    return Path(path).name
