"""The model file: a fitted model saved as one versioned, human-readable JSON file.

``hysbench fit DATASET --model M --save MODEL.json`` writes it; ``load_model(path)`` reads it
back into a ``FittedModel`` whose ``simulate`` gives exactly the fitted model's output (floats are
written with Python's shortest round-trip repr, so every parameter comes back bit for bit).
No pickle: the file names the model by its registry name and hyperparameters and rebuilds it.

Fields (all required; ``FORMAT_VERSION`` is the version this code writes and the only one it reads):

    format               "hysbench-model"
    format_version       integer
    model                registry name, e.g. "mrpim"
    hyperparameters      the constructor arguments
    params               name -> value, every parameter of the model
    input_range          [u_min, u_max] of the identification records: fixes play thresholds, grids
    input_unit, output_unit   the dataset's units ("" when it states none)
    param_units          name -> each parameter's unit in those units (models/units.py; "" dimensionless);
                         written for readers outside Python, not read back (the model declares them)
    sample_time          the identification records' sample time (s): the dt to step the model at
    scale                the data scale {u, y, time} the default bounds were scaled with
    dataset              {name, content_hash}
    identifier           {method, seed, options}
    scores               {validation_e_rms, validation_e_m (worst validation record, percent), records}
    hysbench_version     the hysbench that wrote the file
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import stat
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .base import HysteresisModel
from .errors import HysbenchError, ModelError
from .inverse import StepInvertible
from .registry import get_model
from .stepper import InverseStepper, Stepper

FORMAT = "hysbench-model"
FORMAT_VERSION = 1
REQUIRED = ("format", "format_version", "model", "hyperparameters", "params", "input_range", "input_unit",
            "output_unit", "sample_time", "scale", "dataset", "identifier", "scores", "hysbench_version")


class ModelFileError(HysbenchError):
    """A model file that cannot be read: missing, malformed, of another format version, or naming an unknown model."""


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("hysbench")
    except PackageNotFoundError:  # a source tree that is not installed
        return "0+unknown"


def _plain(obj):
    """JSON-ready: numpy scalars and arrays as Python values, tuples as lists, non-finite floats as None."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple, np.ndarray)):
        return [_plain(v) for v in (obj.tolist() if isinstance(obj, np.ndarray) else obj)]
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(float(obj)) else None
    return obj


def _shown(value) -> str:
    """A JSON value for a message, cut short (a file's content is not echoed at length)."""
    text = json.dumps(value, default=repr)
    return text if len(text) <= 40 else text[:37] + "..."


def _number(where: str, key: str, value) -> float:
    """A model file's number as a finite float: a JSON number, not true/false, not null, not beyond a float."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ModelFileError(f"{where}: {key} must be a number, got {_shown(value)}")
    try:
        x = float(value)
    except OverflowError:
        x = math.inf
    if not math.isfinite(x):
        raise ModelFileError(f"{where}: {key} is not a finite number")
    return x


@dataclass
class FittedModel:
    """A model with its identified parameters and the input range that fixes its structure.

    ``simulate(u, dt=None)``, ``stepper(dt=None)``, ``inverse_stepper(dt=None, ...)`` and ``invert``
    default ``dt`` to ``sample_time``.

    Attributes
    ----------
    model : HysteresisModel
        The model, built from its registry name and hyperparameters.
    params : dict[str, float]
        Every parameter, name -> value, in the model's ``param_names`` order.
    input_range : tuple[float, float]
        (min, max) of the identification input, input unit: fixes input-dependent structure.
    sample_time : float
        The sample time, s, of the data it was identified on (the default ``dt``).
    metadata : dict
        The model file's other fields (``input_unit``, ``output_unit``, ``scale``, ``dataset``,
        ``identifier``, ``scores``: worst validation e_rms and e_m in percent of the measured
        peak-to-peak, ``hysbench_version``), as read or as the identification gave them.
    name : str
        The model's registry name (a property).
    reference_scale : float
        Output unit: the |y| a P-I-family inverse's reach tolerance is relative to, the recorded data
        scale's y (1 where none is recorded); the default of ``inverse_stepper`` and of the exported C
        inverse (a property).
    """

    model: HysteresisModel
    params: dict[str, float]
    input_range: tuple[float, float]
    sample_time: float
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        self._vector = self.model.pack(self.params)
        self.params = self.model.unpack(self._vector)  # every parameter, in order
        self.input_range = (float(self.input_range[0]), float(self.input_range[1]))

    @property
    def name(self) -> str:
        """The model's registry name."""
        return self.model.name

    def _dt(self, dt) -> float:
        return float(self.sample_time if dt is None else dt)

    def simulate(self, u, dt: float | None = None) -> np.ndarray:
        """The model's output for input ``u`` (from rest), as the fit computed it."""
        return self.model.simulate(u, self._dt(dt), self._vector, input_range=self.input_range)

    def stepper(self, dt: float | None = None) -> Stepper:
        return self.model.stepper(self._dt(dt), self.params, input_range=self.input_range)

    @property
    def reference_scale(self) -> float:
        """The |y| a P-I-family inverse's reach tolerance 1e-12 (1 + scale) is relative to, unless given:
        the data scale's y the model file records (1 where it records none). ``inverse_stepper`` and
        ``hysbench export`` both take it, so the Python inverse stepper and the exported C inverse run
        the same search and agree sample by sample."""
        value = (self.metadata.get("scale") or {}).get("y")
        return abs(float(value)) if value else 1.0

    def inverse_stepper(self, dt: float | None = None, input_limits=None, **options) -> InverseStepper:
        """The model's causal inverse stepper; options as the model's ``inverse_stepper``. A P-I-family
        model's ``reference_scale`` defaults to ``self.reference_scale``, the exported C's."""
        if isinstance(self.model, StepInvertible) and options.get("reference_scale") is None:
            options["reference_scale"] = self.reference_scale
        return self.model.inverse_stepper(self._dt(dt), self.params, input_range=self.input_range,
                                          input_limits=input_limits, **options)

    def invert(self, y_desired, dt: float | None = None, input_limits=None, **options):
        return self.model.invert(y_desired, self._dt(dt), self.params, input_range=self.input_range,
                                 input_limits=input_limits, **options)

    # --- the file ----------------------------------------------------------
    def to_dict(self) -> dict:
        meta = self.metadata
        return _plain({
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "model": self.model.name,
            "hyperparameters": self.model.get_hyperparameters(),
            "params": self.params,
            "param_units": self.model.parameter_units(meta.get("input_unit", ""), meta.get("output_unit", "")),
            "input_range": list(self.input_range),
            "input_unit": meta.get("input_unit", ""),
            "output_unit": meta.get("output_unit", ""),
            "sample_time": self.sample_time,
            "scale": meta.get("scale", {}),
            "dataset": meta.get("dataset", {"name": "", "content_hash": ""}),
            "identifier": meta.get("identifier", {"method": "", "seed": None, "options": {}}),
            "scores": meta.get("scores", {"validation_e_rms": None, "validation_e_m": None, "records": []}),
            "hysbench_version": meta.get("hysbench_version") or _version(),
        })

    def to_json(self) -> str:
        return json.dumps(self.to_dict(), indent=2, allow_nan=False) + "\n"

    def save(self, path: str | os.PathLike) -> Path:
        """Write the model file atomically (a temporary sibling renamed: never half-written)."""
        path = Path(path)
        text = self.to_json()
        folder = path.resolve().parent
        if not folder.is_dir():
            raise ModelFileError(f"cannot write {path}: folder {folder} does not exist")
        fd, tmp = tempfile.mkstemp(dir=folder, prefix=f".{path.name}.", suffix=".tmp")
        try:
            with os.fdopen(fd, "w") as f:
                f.write(text)
            os.replace(tmp, path)
        except OSError as exc:
            Path(tmp).unlink(missing_ok=True)
            raise ModelFileError(f"cannot write {path}: {exc.strerror or exc}") from None
        return path

    @classmethod
    def from_dict(cls, d, where: str = "model file") -> "FittedModel":
        if not isinstance(d, dict) or d.get("format") != FORMAT:
            other = d.get("format") if isinstance(d, dict) else None
            if isinstance(other, str):  # e.g. a fit's result (hysbench fit --json)
                raise ModelFileError(f"{where}: a file of format {other[:80]!r}, not a hysbench model file "
                                     f"({FORMAT!r}); a model file is written by hysbench fit ... --save MODEL.json")
            raise ModelFileError(f"{where}: not a hysbench model file (no \"format\": {FORMAT!r})")
        version = d.get("format_version")
        if type(version) is not int or version != FORMAT_VERSION:  # type(): true and 1.0 are not 1 here
            found = (f"format_version {json.dumps(version, default=repr)}" if "format_version" in d
                     else "no format_version")
            advice = "; upgrade hysbench" if type(version) is int and version > FORMAT_VERSION else ""
            raise ModelFileError(f"{where}: {found}, but this hysbench reads format_version {FORMAT_VERSION} "
                                 f"only{advice}")
        missing = [k for k in REQUIRED if k not in d]
        if missing:
            raise ModelFileError(f"{where}: missing field(s) {', '.join(missing)}")
        if not isinstance(d["hyperparameters"], dict) or not isinstance(d["params"], dict):
            raise ModelFileError(f"{where}: hyperparameters and params must be JSON objects")
        if not isinstance(d["model"], str):
            raise ModelFileError(f"{where}: model must be a registry name (a string), got {_shown(d['model'])}")
        try:
            model = get_model(d["model"], **d["hyperparameters"])
        except ModelError as exc:
            raise ModelFileError(f"{where}: {exc}") from None
        if not (isinstance(d["input_range"], list) and len(d["input_range"]) == 2):
            raise ModelFileError(f"{where}: input_range must be [low, high], got {_shown(d['input_range'])}")
        params = {str(k): _number(where, f"params.{k}", v) for k, v in d["params"].items()}
        lo, hi = (_number(where, "input_range", v) for v in d["input_range"])
        dt = _number(where, "sample_time", d["sample_time"])
        if not hi >= lo:
            raise ModelFileError(f"{where}: input_range must be two finite numbers low <= high, got {d['input_range']!r}")
        if not dt > 0:
            raise ModelFileError(f"{where}: sample_time must be positive, got {d['sample_time']!r}")
        for key in ("scale", "dataset", "identifier", "scores"):
            if not isinstance(d[key], dict):
                raise ModelFileError(f"{where}: {key} must be a JSON object, got {_shown(d[key])}")
        for key, value in d["scale"].items():  # null: a scale the fit could not state
            if value is not None and not _number(where, f"scale.{key}", value) > 0:
                raise ModelFileError(f"{where}: scale.{key} must be positive, got {value!r}")
        for key in ("input_unit", "output_unit", "hysbench_version"):
            if not isinstance(d[key], str):
                raise ModelFileError(f"{where}: {key} must be a string, got {_shown(d[key])}")
        try:
            model.pack(params)
        except ModelError as exc:
            raise ModelFileError(f"{where}: {exc}") from None
        meta = {k: d[k] for k in ("input_unit", "output_unit", "scale", "dataset", "identifier", "scores",
                                  "hysbench_version")}
        return cls(model, params, (lo, hi), dt, meta)


def file_sha256(path: str | os.PathLike) -> str:
    """SHA-256 of a file's bytes (the generated C names its model file by it)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def load_model(path: str | os.PathLike) -> FittedModel:
    """The ``FittedModel`` a model file holds; ModelFileError (one line) when it cannot be read."""
    path = Path(path)
    try:
        mode = os.stat(path).st_mode
    except FileNotFoundError:
        raise ModelFileError(f"model file {path} does not exist") from None
    except OSError as exc:
        raise ModelFileError(f"cannot read model file {path}: {exc.strerror or exc}") from None
    if stat.S_ISDIR(mode):
        raise ModelFileError(f"model file {path} is a folder")
    if not stat.S_ISREG(mode):  # a FIFO or a device would be read forever
        raise ModelFileError(f"model file {path} is not a regular file (a device, FIFO or socket)")
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise ModelFileError(f"cannot read model file {path}: {exc}") from None
    try:
        d = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ModelFileError(f"{path}: not JSON ({exc.msg}, line {exc.lineno})") from None
    except ValueError:  # an integer of more digits than Python converts
        raise ModelFileError(f"{path}: not JSON this hysbench reads (an integer with too many digits)") from None
    except RecursionError:
        raise ModelFileError(f"{path}: not JSON this hysbench reads (arrays or objects nested too deeply)") from None
    return FittedModel.from_dict(d, where=str(path))
