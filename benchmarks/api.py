"""The functions behind ``import hysbench as hb``: ``load_dataset``, ``get_model``, ``list_models``,
``identify``, ``run_matrix`` and ``diagnose``, each with the shipped virtual DEA as its default dataset.

The package ``hysbench`` (benchmarks/hysbench/__init__.py) loads this module on first use of one of
these names, so importing a layer (``hysbench.models``, ...) does not import the benchmarks.
"""

from __future__ import annotations

import os
import tempfile

from hysbench.benchmarks.diagnosis import diagnose as diagnose_model
from hysbench.benchmarks.matrix.cells import method_options, plan_cells
from hysbench.benchmarks.matrix.execute import run_matrix as run_cells
from hysbench.benchmarks.matrix.store import CellStore
from hysbench.data.dataset import load_dataset as load_folder
from hysbench.data.virtual_dea import default_dataset_path
from hysbench.identification.api import identify as identify_model
from hysbench.models.model_file import load_model as load_model_file
from hysbench.models.registry import get_model as registry_model, list_models as registry_names

__all__ = ["diagnose", "get_model", "identify", "list_models", "load_dataset", "load_model", "run_matrix"]


def load_dataset(path: str | os.PathLike | None = None):
    """Read and check a dataset folder (or its ``dataset.toml``); ``None``: the shipped virtual DEA.

    Returns a ``hysbench.data.Dataset``: its ``records`` each hold ``t``, ``u``, ``y``, ``role``
    (``"identification"`` or ``"validation"``), ``frequency_hz`` and the scored window.
    A folder the loader refuses raises ``hysbench.data.DatasetError`` naming the file and the problem.

    Example::

        >>> import hysbench as hb
        >>> ds = hb.load_dataset()
        >>> [r.frequency_hz for r in ds.records if r.role == "validation"]
        [0.05, 0.2, 0.8]
    """
    return load_folder(default_dataset_path() if path is None else path)


def get_model(name: str, **hyperparameters):
    """A registered model by name, its hyperparameters as keyword arguments (``hb.list_models()``).

    Example::

        >>> import hysbench as hb
        >>> model = hb.get_model("mrpim", offset=False)
        >>> model.n_params
        20
        >>> y = model.simulate(u, dt, model.preset("paper"))    # doctest: +SKIP
    """
    return registry_model(name, **hyperparameters)


def list_models(matrix_only: bool = False) -> list[str]:
    """Registered model names; ``matrix_only``: those ``hysbench run`` scores by default.

    Example::

        >>> import hysbench as hb
        >>> "mrpim" in hb.list_models(matrix_only=True)
        True
    """
    return registry_names(matrix_only=matrix_only)


def identify(model, dataset=None, method: str = "auto", seed: int | None = 0, **options):
    """Identify ``model`` (a name or a model object) on the dataset's identification records.

    ``dataset``: a ``Dataset``, a folder, or ``None`` for the shipped virtual DEA. ``method``:
    ``varpro``, ``mpso``, ``lsq``, ``varpro+lsq``, ``mpso+lsq`` or ``auto``; ``options`` are the
    identifier's (e.g. ``n_starts=4``). Returns a ``hysbench.identification.Fit``: ``params``,
    ``fitness`` (eq. 9), ``records`` (e_m and e_rms per record), ``simulate(u, dt)``.

    Example::

        >>> import hysbench as hb
        >>> fit = hb.identify("classical-pi", method="varpro", seed=0)
        >>> sorted({score.role for score in fit.records})
        ['identification', 'validation']
    """
    return identify_model(model, load_dataset() if dataset is None else dataset, method=method, seed=seed, **options)


def run_matrix(datasets=None, models: list[str] | None = None, methods: list[str] | None = None, seed: int = 0,
               options: dict | None = None, jobs: int = 1, out: str | os.PathLike | None = None) -> list[dict]:
    """Every model x applicable identifier on every dataset, as ``hysbench run`` computes it.

    ``datasets``: one folder or a list of folders (``None``: the shipped virtual DEA); ``models`` and
    ``methods``: registry names and identifiers (``None``: the matrix's defaults); ``options``: per
    identifier, e.g. ``{"lsq": {"max_nfev": 60}}``, on top of the matrix's budgets. Finished
    cells are kept in ``out``/cells (``None``: a temporary folder, removed afterwards), so a second call
    with the same ``out`` computes only what is missing. Returns one dict per cell (keys ``model``,
    ``method``, ``status``, ``params``, ``records`` with e_m and e_rms, ``fit_seconds``, ...; every key
    is documented in ``hysbench.benchmarks.matrix.cells.CellResult``), in the matrix's order. Writes no report; ``hysbench run`` does.

    Example::

        >>> import hysbench as hb
        >>> rows = hb.run_matrix(models=["classical-pi"], methods=["varpro"])
        >>> [(r["model"], r["method"], r["status"]) for r in rows]
        [('classical-pi', 'varpro', 'ok')]
    """
    if datasets is None:
        datasets = [default_dataset_path()]
    elif isinstance(datasets, (str, os.PathLike)):
        datasets = [datasets]
    loaded = [(str(path), load_folder(path)) for path in datasets]
    cells = plan_cells(loaded, models, methods, seed, method_options(methods, dict(options or {}), False))
    with tempfile.TemporaryDirectory(prefix="hysbench-matrix-") as scratch:
        results = run_cells(cells, CellStore(scratch if out is None else out), jobs=jobs, quiet=True)
        return [results[cell.key] for cell in cells]


def diagnose(dataset=None, model: str = "mrpim", seed: int = 0, **settings):
    """What ``model`` gets wrong on ``dataset`` (``None``: the shipped virtual DEA): the cause, the
    extension that models it and the gain on the validation records, as ``hysbench diagnose`` reports it.

    ``settings`` are those of ``hysbench.benchmarks.diagnosis.diagnose`` (``segments``, ``experiments``,
    ``thorough``, ...). Returns a ``Diagnosis``: ``cause`` (a cause, ``"none"`` or ``"unexplained"``),
    ``verdict``, ``candidates``, ``extended_fit``, ``before`` and ``after`` (residuals per record).
    The decision rule is in docs/diagnosis.md.

    Example::

        >>> import hysbench as hb
        >>> diag = hb.diagnose(model="mrpim", seed=0)     # doctest: +SKIP
        >>> diag.cause                                     # doctest: +SKIP
        'relaxation'

    (The example takes about half a minute on two cores.)
    """
    return diagnose_model(load_dataset() if dataset is None else dataset, model, seed=seed, **settings)


def load_model(path: str | os.PathLike):
    """A fitted model saved by ``hysbench fit ... --save MODEL.json`` (or ``FittedModel.save``).

    Returns a ``hysbench.models.FittedModel``: ``simulate(u, dt)`` gives the fitted model's output
    bit for bit, ``stepper(dt)`` and ``inverse_stepper(dt)`` advance it one sample at a time.
    A file of another format version or with a missing field raises ``ModelFileError`` in one line.

    Example::

        >>> import hysbench as hb
        >>> model = hb.load_model("m.json")                   # doctest: +SKIP
        >>> s = model.stepper()                               # doctest: +SKIP
        >>> y = [s.step(v) for v in u]                        # doctest: +SKIP
    """
    return load_model_file(path)
