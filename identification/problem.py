"""What every identifier minimises: eq. 9 over the scored windows of the fit records.

    f(theta) = sum_m k_m / n_m sum_{i in window m} (y_mi(theta) - y^a_mi)^2

A ``Problem`` holds the fit records, the data scale and bounds, the input
range that fixes the model's structure, and counts model evaluations. One
evaluation is one parameter set simulated over every fit record (for varpro:
one regressor build over every fit record for one nonlinear parameter set).
Residual vectors are stacked over records with row weights sqrt(k_m / n_m),
so that their sum of squares is eq. 9 exactly.

Identifiers use the model only through its interface: ``simulate_window_batch``,
``windowed_regressors_batch``, ``parameters``/``bounds``, names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping, Sequence

import numpy as np

from hysbench.data.protocol import input_range as records_input_range
from hysbench.data.dataset import Record, scale_of_outputs
from hysbench.data.excitations import shortest_period
from hysbench.data.segments import own_stretch
from hysbench.models.base import DataScale, HysteresisModel

from .errors import IdentificationError

# Largest batch output simulated at once (elements of the (sets, samples) array).
MAX_BATCH_ELEMENTS = 20_000_000


def drive_time(record: Record) -> float:
    """A fit record's shortest drive period: 1 / its nominal frequency, or for a record without one 1 / the
    high end of its scored window's input band (``shortest_period``)."""
    return shortest_period(record.u[record.scored], record.dt, record.frequency_hz)


def data_scale(records: Sequence[Record], stretches: Sequence[slice] | None = None) -> DataScale:
    """DataScale of the fit records: max |u| over the whole records (the input a simulation is driven by),
    max |y| over each record's ``stretches`` (the outputs a fit may read, ``own_stretch``; default: whole
    records) and the shortest drive period (``drive_time``)."""
    stretches = stretches or [slice(None)] * len(records)
    return DataScale.of([r.u for r in records], [r.y[s] for r, s in zip(records, stretches)],
                        time=min(drive_time(r) for r in records))


def fit_output_scale(records: Sequence[Record]) -> float:
    """The power of two the residuals are divided by (``scale_of_outputs`` of the scored outputs: 1 at
    ordinary scales, so fits there are unchanged to the last bit; data at 1e-200 or 1e+90 fitted at order one)."""
    return scale_of_outputs(r.y[r.scored] for r in records)


@dataclass
class Problem:
    """A prepared identification problem; see the module docstring."""

    model: HysteresisModel
    records: list[Record]
    scale: DataScale
    lower: np.ndarray
    upper: np.ndarray
    input_range: tuple[float, float]
    n_evaluations: int = 0
    history: list[tuple[int, float]] = field(default_factory=list)
    best_fitness: float = math.inf
    n_nonfinite: int = 0  # evaluated parameter sets whose model output was not finite
    data_start: dict | None = None  # the model's start from the data (``start_from_data``), if it has one
    output_scale: float = 1.0  # residuals are divided by it (``fit_output_scale``); fitness is reported unscaled
    stretches: list | None = None  # per record, the samples whose output the fit may read (``own_stretch``)

    @classmethod
    def build(cls, model: HysteresisModel, records: Sequence[Record],
              bounds: Mapping[str, Sequence[float]] | None = None, others: Sequence[Record] = ()) -> "Problem":
        """``others``: the dataset's other records; the output a fit reads stops at their scored windows
        (``own_stretch``: a validation window of the same recording is never read)."""
        records = list(records)
        stretches = [own_stretch(r, [*records, *others]) for r in records]
        if records and not any(r.weight > 0 for r in records):
            raise IdentificationError(f"every fit record ({', '.join(r.file for r in records)}) has weight 0: "
                                      "eq. 9 has nothing to fit")
        if records and model.n_params > sum(r.n_scored for r in records):
            raise IdentificationError(
                f"model {model.name!r} has {model.n_params} parameters, more than the {sum(r.n_scored for r in records)} "
                "scored samples of the fit records: nothing determines them (use fewer operators or longer windows)")
        scale = data_scale(records, stretches)
        lower, upper = (np.array(b, dtype=float) for b in model.bounds(scale))
        names = model.param_names
        informed = model.start_from_data([(r.u, r.y, r.dt, r.scored) for r in records], scale)
        data_start, data_bounds = informed if informed is not None else (None, {})
        for name, pair in {**data_bounds, **(bounds or {})}.items():
            if name not in names:
                raise IdentificationError(
                    f"bounds: model {model.name!r} has no parameter {name!r} (parameters: {', '.join(names)})")
            try:
                lo, hi = (float(v) for v in pair)
            except (TypeError, ValueError):
                raise IdentificationError(f"bounds for {name!r} must be a pair [low, high], got {pair!r}") from None
            if not (lo <= hi) or math.isnan(lo) or math.isnan(hi):
                raise IdentificationError(f"bounds for {name!r}: low {lo!r} is not <= high {hi!r}")
            i = names.index(name)
            lower[i], upper[i] = lo, hi
        return cls(model, records, scale, lower, upper, records_input_range(records), data_start=data_start,
                   output_scale=fit_output_scale(records), stretches=stretches)

    @classmethod
    def for_fit(cls, fit, dataset) -> "Problem":
        """The problem a Fit solved: its model, fitted records and bounds (e.g.
        to get varpro's linear solve around a fit's optimum)."""
        records = [dataset.record(f) for f in fit.fitted_on]
        return cls.build(fit.model_instance(), records, fit.bounds)

    # --- sizes and names -------------------------------------------------
    @property
    def names(self) -> tuple[str, ...]:
        return self.model.param_names

    @property
    def row_weights(self) -> list[float]:
        """sqrt(k_m / n_m) per record: weighted squared residuals sum to eq. 9."""
        return [math.sqrt(r.weight / r.n_scored) for r in self.records]

    @property
    def n_rows(self) -> int:
        return sum(r.n_scored for r in self.records)

    def clip(self, x: np.ndarray) -> np.ndarray:
        return np.minimum(np.maximum(x, self.lower), self.upper)

    # --- evaluation ------------------------------------------------------
    def residuals_batch(self, P: np.ndarray) -> np.ndarray:
        """Weighted residuals (n_sets, n_rows) for parameter sets in ``param_names`` order, divided by
        ``output_scale`` (a power of two, 1 at ordinary scales: ``fit_output_scale``).

        Each record is simulated for the whole batch in one
        ``simulate_window_batch`` call (split only when the output would exceed
        MAX_BATCH_ELEMENTS).
        A parameter set whose model output is not finite gets +inf residuals, so that a
        search moves away from it; such sets are counted in ``n_nonfinite`` and the Fit
        reports them (never scored silently).
        """
        P = np.atleast_2d(np.asarray(P, dtype=float))
        n_set = P.shape[0]
        out = np.empty((n_set, self.n_rows))
        starts = np.cumsum([0] + [r.n_scored for r in self.records])
        # the base class's window is a slice of the full output: size its batches by the record
        windowed = type(self.model).simulate_window_batch is not HysteresisModel.simulate_window_batch
        scale = self.output_scale

        def one(m):
            r, w, col = self.records[m], self.row_weights[m], starts[m]
            chunk = max(1, MAX_BATCH_ELEMENTS // (r.n_scored if windowed else r.u.size))
            ya = r.y[r.scored]
            for a in range(0, n_set, chunk):
                Y = self.model.simulate_window_batch(r.u, r.dt, P[a:a + chunk], r.scored, input_range=self.input_range)
                out[a:a + chunk, col:col + r.n_scored] = w * (Y - ya) if scale == 1.0 else w * ((Y - ya) / scale)

        for m in range(len(self.records)):
            one(m)
        bad = ~np.isfinite(out)
        if bad.any():
            self.n_nonfinite += int(np.count_nonzero(bad.any(axis=1)))
            out[bad] = np.inf
        self.n_evaluations += n_set
        return out

    def fitness_batch(self, P: np.ndarray) -> np.ndarray:
        """Eq. 9 for each parameter set; records the best so far in ``history``."""
        R = self.residuals_batch(P)
        with np.errstate(over="ignore", invalid="ignore"):
            f = np.einsum("ij,ij->i", R, R)
        f[~np.isfinite(f)] = np.inf
        self.note(float(np.min(f)) * self.output_scale**2 if f.size else math.inf)
        return f

    def note(self, fitness: float) -> None:
        """Record an evaluated fitness in the convergence history (best so far)."""
        if fitness < self.best_fitness:
            self.best_fitness = fitness
        self.history.append((self.n_evaluations, self.best_fitness))

    def vector(self, params: Mapping[str, float]) -> np.ndarray:
        return self.model.pack(params)

    def start_vector(self, start: Mapping[str, float] | None) -> np.ndarray:
        """Default parameters (the model's start from the data, if it has one; clipped into bounds)
        overridden by ``start``."""
        defaults = {**self.model.default_params(self.scale), **(self.data_start or {})}
        x = self.clip(np.array(self.model.pack(defaults), dtype=float))
        for name, value in (start or {}).items():
            if name not in self.names:
                raise IdentificationError(
                    f"start: model {self.model.name!r} has no parameter {name!r} (parameters: {', '.join(self.names)})")
            x[self.names.index(name)] = float(value)
        return self.clip(x)
