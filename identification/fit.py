"""``Fit``: the one result type of every identifier (lmfit style).

A Fit names the model (registry name and hyperparameters) and the method,
holds the parameters, eq. 9's fitness on the fit records, e_m and e_rms of
every record of the dataset (identification and validation), the number of
model evaluations, the wall time, the convergence history, the input range
that fixes the model's structure, the bounds, options and seed; whether it
succeeded (``success`` is False when the model's output is not finite at the
identified parameters: such a fit is never scored), which parameters the
scored data do not determine and were fixed (``undetermined``; varpro's
linear solve, identification/linear.py), how many evaluated
parameter sets gave non-finite output, and AIC / BIC computed once from eq. 9's
fitness as a Gaussian likelihood with n = the scored rows of the fit records
and k = the free parameters (identification/criteria.py; residuals are
correlated, so these favour bigger models: the ablation and the diagnosis use
the effective-sample-size forms). ``input_unit`` and ``output_unit`` are the
dataset's units ("" when it names none): the fitness is in the output unit
squared, and each parameter's unit (``param_units``) is written in them. It
simulates new inputs and round-trips through JSON (``to_dict`` / ``from_dict``;
a fit written without a unit reads as naming none).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from hysbench.data.protocol import RecordScore, score_records
from hysbench.data.dataset import Record
from hysbench.data.files import jsonable
from hysbench.models import get_model
from hysbench.models.base import HysteresisModel
from hysbench.models.model_file import FittedModel

from .errors import IdentificationError

FORMAT = "hysbench-fit/1"


def _float(x):
    return math.nan if x is None else float(x)


def squared_unit(unit: str) -> str:
    """A unit squared as the summary prints it: "mm" -> "mm²", "m/s" -> "(m/s)²", "" -> ""."""
    unit = unit.strip()
    if not unit:
        return ""
    return f"{unit}²" if re.fullmatch(r"[^\W\d_]+", unit) else f"({unit})²"


def _percent(x: float) -> str:
    """An error in % for the summary's table: three decimals, or three digits once it is too large for them."""
    return _shown(x, "8.3f" if abs(x) < 1e5 else "8.3g")


def _shown(x: float, spec: str) -> str:
    """A number as the summary prints it; a non-finite one as "non-finite" (never nan or inf)."""
    return format(x, spec) if math.isfinite(x) else "non-finite"


@dataclass
class Fit:
    """What an identification returns: the one result type of every identifier.

    Every public attribute is listed here (``help(Fit)``); e_m and e_rms are in percent of the measured
    peak-to-peak of each record's scored window (eq. 10), the fitness is in the output unit squared (eq. 9).

    Attributes
    ----------
    model : str
        The model's registry name.
    hyperparameters : dict
        The model's constructor arguments (``get_hyperparameters()``).
    method : str
        The identifier that ran: ``varpro``, ``mpso``, ``lsq``, ``native`` or a chain such as ``varpro+lsq``.
    params : dict[str, float]
        The identified parameters, name -> value, in the model's ``param_names`` order.
    n_params : int
        The number of parameters (``len(params)``; a property).
    fitness : float
        Eq. 9 on the scored windows of the fit records: their weighted mean squared error, in
        ``output_unit`` squared; NaN when the fit failed.
    records : list[RecordScore]
        One per record of the dataset: ``file``, ``frequency_hz`` (Hz or None), ``role``
        ("identification" if fitted, else "validation"), ``e_m`` and ``e_rms`` (%).
    n_evaluations : int
        Model evaluations of the search (the final scoring is not counted).
    fit_seconds : float
        Wall time of the search and final solve, s (not the scoring of every record).
    history : list[tuple[int, float]]
        Convergence: (evaluations so far, best eq. 9 fitness so far in ``output_unit`` squared).
    input_range : tuple[float, float]
        (min, max) of the input over the fit records, input unit: fixes input-dependent structure
        (play thresholds, a Preisach grid) for every later simulation.
    bounds : dict[str, tuple[float, float]]
        Each parameter's (low, high) bounds of the search (equal: fixed).
    scale : dict[str, float]
        The fit records' data scale the default bounds follow: ``u`` max |input|, ``y`` max |output|
        (their units), ``time`` the shortest drive period (s).
    options : dict
        The identifier's options per stage (stage name -> ``get_params()``) and the common options
        given (``fit_on``, ``bounds``, ``start``).
    seed : int or None
        The seed of the search.
    dataset : str
        The dataset's name.
    dataset_hash : str
        ``Dataset.content_hash()`` of the dataset (SHA-256, hex).
    fitted_on : list[str]
        File names of the fit records.
    diagnostics : dict
        Per stage the method's diagnostics (condition numbers, local searches, ...) and ``at_bounds``,
        the parameters that ended at a bound.
    notes : list[str]
        Warnings in words (parameters at bounds, non-finite evaluations, undetermined parameters).
    version : str
        The hysbench version that computed the fit ("" when unknown).
    success : bool
        False when the model's output is not finite at the identified parameters (such a fit is not scored).
    message : str
        One line on how the fit ended.
    n_nonfinite : int
        Evaluated parameter sets whose model output was not finite.
    n_rows : int
        Scored samples of the fit records (the n of AIC and BIC).
    aic, bic : float
        Akaike and Bayesian information criteria from eq. 9's fitness as a Gaussian likelihood
        (n = ``n_rows``, k = the free parameters; identification/criteria.py); NaN when the fit failed.
    undetermined : list[str]
        Parameters the scored data do not determine, fixed by varpro's linear solve.
    output_unit : str
        The dataset's output unit ("" when it names none): ``fitness`` is in its square.
    input_unit : str
        The dataset's input unit ("" when it names none).
    param_units : dict[str, str]
        Each parameter's unit in the dataset's units, e.g. ``{"a1": "mm/kV", "gamma": "s"}`` ("" for a
        dimensionless one; ``in`` and ``out`` stand for units the dataset does not name); a property, from
        the model's declarations (models/units.py).
    """

    model: str
    hyperparameters: dict
    method: str
    params: dict[str, float]
    fitness: float
    records: list[RecordScore]
    n_evaluations: int
    fit_seconds: float
    history: list[tuple[int, float]]
    input_range: tuple[float, float]
    bounds: dict[str, tuple[float, float]]
    scale: dict[str, float]
    options: dict
    seed: int | None
    dataset: str = ""
    dataset_hash: str = ""
    fitted_on: list[str] = field(default_factory=list)
    diagnostics: dict = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    version: str = ""
    success: bool = True
    message: str = ""
    n_nonfinite: int = 0
    n_rows: int = 0
    aic: float = math.nan
    bic: float = math.nan
    undetermined: list[str] = field(default_factory=list)
    output_unit: str = ""
    input_unit: str = ""
    _instance: HysteresisModel | None = field(default=None, repr=False, compare=False)

    # --- the fitted model ----------------------------------------------------
    @property
    def n_params(self) -> int:
        """The number of parameters."""
        return len(self.params)

    def model_instance(self) -> HysteresisModel:
        """The model this Fit belongs to (rebuilt from the registry after from_dict)."""
        if self._instance is None:
            self._instance = get_model(self.model, **self.hyperparameters)
        return self._instance

    def simulate(self, u, dt: float) -> np.ndarray:
        """Output of the fitted model for a new input, from its first sample."""
        return self.model_instance().simulate(u, dt, self.params, input_range=self.input_range)

    @property
    def param_units(self) -> dict[str, str]:
        """Each parameter's unit in the dataset's units ("" dimensionless)."""
        return self.model_instance().parameter_units(self.input_unit, self.output_unit)

    def fitted_model(self, sample_time: float, input_unit: str | None = None,
                     output_unit: str | None = None) -> FittedModel:
        """The fitted model with what its model file records (models/model_file.py): the dataset's
        sample time and units (None: the fit's own), the data scale, the dataset's name
        and hash, the identifier and the worst validation e_rms and e_m."""
        input_unit = self.input_unit if input_unit is None else input_unit
        output_unit = self.output_unit if output_unit is None else output_unit
        if not self.success:
            raise IdentificationError(f"fit of {self.model} failed ({self.message}): no model to save")
        meta = {
            "input_unit": input_unit, "output_unit": output_unit, "scale": dict(self.scale),
            "dataset": {"name": self.dataset, "content_hash": self.dataset_hash},
            "identifier": {"method": self.method, "seed": self.seed, "options": jsonable(self.options)},
            "scores": {"validation_e_rms": self.worst("validation", "e_rms"),
                       "validation_e_m": self.worst("validation", "e_m"),
                       "records": [s.as_dict() for s in self.records]},
            "hysbench_version": self.version,
        }
        return FittedModel(self.model_instance(), dict(self.params), tuple(self.input_range), float(sample_time), meta)

    def predict(self, record: Record) -> np.ndarray:
        return self.simulate(record.u, record.dt)

    def score(self, records: Sequence[Record]) -> list[RecordScore]:
        """e_m and e_rms (percent) of the fitted model on other records."""
        return score_records(self.model_instance(), self.params, records, self.input_range)

    # --- views -----------------------------------------------------------------
    def scores(self, role: str | None = None) -> list[RecordScore]:
        return [s for s in self.records if role is None or s.role == role]

    def worst(self, role: str, metric: str = "e_rms") -> float:
        vals = [getattr(s, metric) for s in self.scores(role)]
        return max(vals) if vals else math.nan

    def mean(self, role: str, metric: str = "e_rms") -> float:
        vals = [getattr(s, metric) for s in self.scores(role)]
        return float(np.mean(vals)) if vals else math.nan

    def summary(self) -> str:
        """A short text table: the fit, per-record errors, parameters."""
        lines = [
            f"model {self.model} ({self.n_params} parameters), method {self.method}, seed {self.seed}",
            f"fitness (eq. 9) {_shown(self.fitness, '.6g')}{self._fitness_unit()}   evaluations {self.n_evaluations}   "
            f"time {self.fit_seconds:.2f} s",
        ]
        if not self.success:
            lines.append(f"FAILED: {self.message}")
        elif self.n_nonfinite:
            lines.append(f"{self.n_nonfinite} evaluated parameter sets gave non-finite model output")
        lines += [
            "",
            f"{'record':<24} {'f (Hz)':>8} {'role':<15} {'e_m %':>8} {'e_rms %':>8}",
        ]
        for s in self.records:
            f = f"{s.frequency_hz:g}" if s.frequency_hz else "-"
            lines.append(f"{s.file:<24} {f:>8} {s.role:<15} {_percent(s.e_m)} {_percent(s.e_rms)}")
        lines.append("")
        units = self.param_units
        items = [f"{k} = {_shown(v, '.6g')}" + (f" {units[k]}" if units.get(k) and math.isfinite(v) else "")
                 for k, v in self.params.items()]
        width = max(20, *(len(it) for it in items)) if items else 20
        for i in range(0, len(items), 4):
            lines.append("   ".join(f"{it:<{width}}" for it in items[i:i + 4]).rstrip())
        if not (self.input_unit and self.output_unit) and any(units.values()):
            lines.append("(in, out: the input's and the output's units, which the dataset does not name)")
        if self.undetermined:
            lines += ["", "undetermined by the scored data (fixed): " + ", ".join(
                f"{n} = {_shown(self.params.get(n, math.nan), '.6g')}" for n in self.undetermined)]
        for note in self.notes:
            lines += ["", f"note: {note}"]
        return "\n".join(lines)

    def _fitness_unit(self) -> str:
        """" mm²" after a finite fitness when the dataset names its output unit, else nothing."""
        unit = squared_unit(self.output_unit)
        return f" {unit}" if unit and math.isfinite(self.fitness) else ""

    # --- JSON ------------------------------------------------------------------
    def to_dict(self) -> dict:
        return jsonable({
            "format": FORMAT,
            "model": self.model,
            "hyperparameters": self.hyperparameters,
            "method": self.method,
            "n_params": self.n_params,
            "params": self.params,
            "fitness": self.fitness,
            "output_unit": self.output_unit,
            "input_unit": self.input_unit,
            "param_units": self.param_units,
            "fit_seconds": self.fit_seconds,
            "n_evaluations": self.n_evaluations,
            "records": [s.as_dict() for s in self.records],
            "seed": self.seed,
            "dataset": self.dataset,
            "dataset_hash": self.dataset_hash,
            "fitted_on": self.fitted_on,
            "input_range": list(self.input_range),
            "bounds": {k: list(v) for k, v in self.bounds.items()},
            "scale": self.scale,
            "options": self.options,
            "history": [list(h) for h in self.history],
            "diagnostics": self.diagnostics,
            "notes": self.notes,
            "version": self.version,
            "success": self.success,
            "message": self.message,
            "n_nonfinite": self.n_nonfinite,
            "n_rows": self.n_rows,
            "aic": self.aic,
            "bic": self.bic,
            "undetermined": list(self.undetermined),
        })

    @classmethod
    def from_dict(cls, d: dict) -> "Fit":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            raise IdentificationError(f"not a hysbench fit (expected format {FORMAT!r})")
        try:
            return cls(
                model=d["model"],
                hyperparameters=dict(d["hyperparameters"]),
                method=d["method"],
                params={k: _float(v) for k, v in d["params"].items()},
                fitness=_float(d["fitness"]),
                records=[RecordScore(r["file"], r["frequency_hz"], r["role"], _float(r["e_m"]), _float(r["e_rms"]))
                         for r in d["records"]],
                n_evaluations=int(d["n_evaluations"]),
                fit_seconds=_float(d["fit_seconds"]),
                history=[(int(n), _float(f)) for n, f in d["history"]],
                input_range=tuple(_float(v) for v in d["input_range"]),
                bounds={k: (-math.inf if v[0] is None else float(v[0]), math.inf if v[1] is None else float(v[1]))
                        for k, v in d["bounds"].items()},
                scale={k: _float(v) for k, v in d["scale"].items()},
                options=d["options"],
                seed=d["seed"],
                dataset=d.get("dataset", ""),
                dataset_hash=d.get("dataset_hash", ""),
                fitted_on=list(d.get("fitted_on", [])),
                diagnostics=d.get("diagnostics", {}),
                notes=list(d.get("notes", [])),
                version=d.get("version", ""),
                success=bool(d.get("success", True)),
                message=d.get("message", ""),
                n_nonfinite=int(d.get("n_nonfinite", 0)),
                n_rows=int(d.get("n_rows", 0)),
                aic=_float(d.get("aic")),
                bic=_float(d.get("bic")),
                undetermined=[str(n) for n in d.get("undetermined", [])],
                output_unit=_unit(d.get("output_unit", ""), "output_unit"),
                input_unit=_unit(d.get("input_unit", ""), "input_unit"),
            )
        except (KeyError, TypeError, ValueError, IndexError) as exc:
            raise IdentificationError(f"malformed fit record: {exc!r}") from None


def _unit(value, key: str) -> str:
    if not isinstance(value, str):
        raise IdentificationError(f"malformed fit record: {key} must be a string, got {value!r}")
    return value
