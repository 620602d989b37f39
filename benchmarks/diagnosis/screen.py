"""The candidate screen: the base model alone (the null) and each cause's extension, fitted on a fixed random
subset of at most ``max_rows`` rows per identification record (the models run over every sample; the subset keeps
the least-squares solves small); linear parameters are solved exactly at every step. The cause is chosen on
held-out records (``selection``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from hysbench.data.dataset import Record
from hysbench.data.excitations import drive_band, shortest_period
from hysbench.identification.criteria import effective_sample_size
from hysbench.models import ExtendedModel
from hysbench.models.base import DataScale, HysteresisModel
from hysbench.models.extended import CREEP_TIME_BOUNDS, RESONANCE_HZ_BOUNDS
from hysbench.models.window import Window

from .candidates import MAX_ROWS, Candidate, column_basis, estimates_of, is_log, solve_scaled
from .causes import CAUSES, cause_of_parameter, refined
from .composite import composite
from .heldout import beyond_others, held_out_windows
from .policy import Policy
from .residuals import RecordResidual

EXACT_GRID_SAMPLES = 300_000
RELAXATION_CACHE = 512  # filtered input rows kept per record (at 10,000 rows: 40 MB per record)


@dataclass
class _Part:
    """One identification record in the screen and its row subset."""
    record: Record
    rows: np.ndarray
    window: Window  # the rows, checked once


@dataclass
class _BaseColumns:
    """The base's regressor columns for one nonlinear parameter set, per record."""
    rows: list  # (n_rows_m, n_base_linear) per record
    full: list | None  # {name: full-length column} per record, or None if not kept


class Screen:
    """The candidate fits. Stage 1 (``Cause.fit``): a cause's extension with the base's nonlinear parameters held
    at the null's; only the components' columns are new, so they are projected off the base's columns and regressed
    on the null's residual (cheap). Stage 2 (``joint``): the base's nonlinear parameters free as well.
    """

    def __init__(self, base: HysteresisModel, base_params: Mapping[str, float], input_range,
                 identification: Sequence[Record], scale: DataScale,
                 noise_sd: float, max_rows: int = MAX_ROWS, seed: int = 0, policy: Policy = Policy()):
        self.policy = policy
        self.base = base
        self.input_range = tuple(input_range)
        self.scale = scale
        self.base_nl_names = base.nonlinear_names
        self.base_lin = base.linear_names
        self.noise_sd = float(noise_sd)
        rng = np.random.default_rng(seed)
        self.parts: list[_Part] = []
        for r in identification:
            n = r.t.size
            rows = np.arange(n) if n <= max_rows else np.sort(rng.choice(n, max_rows, replace=False))
            self.parts.append(_Part(r, rows, Window.of(rows, n)))
        self._relaxation_cache = [{} for _ in self.parts]  # {(tau, power): filtered input at the rows} per record
        self._late_cache = [{} for _ in self.parts]  # a late model's parts per record (``ExtendedModel``)
        self.y = np.concatenate([p.record.y[p.rows] for p in self.parts])
        self.n = self.y.size
        inputs = [p.record.u for p in self.parts]
        self.held_out_windows = held_out_windows(inputs, policy.beyond_range)  # per record: samples predicted from start
        self.scored_rows = [int(np.searchsorted(p.rows, w)) for p, w in zip(self.parts, self.held_out_windows)]
        self.beyond_range = beyond_others(inputs)
        self.n_held_out_rows = sum(self.scored_rows)
        self.drive_time = min(shortest_period(p.record.u, p.record.dt, p.record.frequency_hz) for p in self.parts)
        self.component_scale = replace(scale, time=self.drive_time)  # the causes' time scale
        # the lowest mode frequency searched: 1 / the shortest drive period, or down to the low end of the band of
        # a record without a nominal frequency (a broadband drive excites a mode inside its band, where it shows best)
        bands = [drive_band(p.record.u, p.record.dt) for p in self.parts if not p.record.frequency_hz]
        self.mode_floor = min([RESONANCE_HZ_BOUNDS[0] / self.drive_time, *(b[0] for b in bands if b is not None)])
        self._extension_cache: dict = {}
        self._columns: dict = {}  # base nonlinear tuple -> _BaseColumns (a few, most recent last)
        self.null = self._fit_null({k: float(base_params[k]) for k in self.base_nl_names})

    def extension(self, components: Sequence[str], **hyper) -> ExtendedModel:
        key = (tuple(components), tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in hyper.items())))
        if key not in self._extension_cache:
            self._extension_cache[key] = ExtendedModel(base=self.base.name, components=tuple(components),
                                                       base_hyperparameters=self.base.get_hyperparameters(), **hyper)
        return self._extension_cache[key]

    @property
    def creep_min(self) -> float:
        """Creep is a drift much slower than the drive: at least twice the longest nominal drive period, and
        at least the shortest record's span: 1 / its frequency, or for a record without a nominal frequency its
        scored duration (a spectrum's lowest bins hold a record's fade-in and length, not a drive period)."""
        periods = [1.0 / p.record.frequency_hz for p in self.parts if p.record.frequency_hz]
        spans = [1.0 / r.frequency_hz if r.frequency_hz else r.n_scored * r.dt for r in (p.record for p in self.parts)]
        return max(CREEP_TIME_BOUNDS[0] * min(spans), self.policy.creep_periods * max(periods, default=0.0))

    @property
    def shortest_span(self) -> float:
        """The shortest time span (s) of a record's rows in the screen."""
        return min(float((p.rows[-1] - p.rows[0] + 1) * p.record.dt) for p in self.parts)

    def bounds_of(self, model: HysteresisModel, name: str) -> tuple[float, float]:
        """A parameter's search bounds: the base's from the data scale, a cause's from the drive's periods."""
        scale = self.scale if name in self.base.param_names else self.component_scale
        for p in model.parameters(scale):
            if p.name == name:
                owner = cause_of_parameter(name)
                lo, hi = float(p.min), float(p.max)
                return owner.bounds(self, name, lo, hi) if owner is not None else (lo, hi)
        raise KeyError(name)

    @property
    def nyquist(self) -> float:
        """The Nyquist frequency (Hz) of the most coarsely sampled record."""
        return 0.5 / max(p.record.dt for p in self.parts)

    def base_columns(self, base_nl: Mapping[str, float], full: bool = False) -> _BaseColumns:
        """The base's regressors for these nonlinear parameters (cached for the last few sets)."""
        key = tuple(float(base_nl[k]) for k in self.base_nl_names)
        cols = self._columns.get(key)
        if cols is not None and (cols.full is not None or not full):
            self._columns[key] = self._columns.pop(key)  # most recent last
            return cols
        rows, fulls = [], []
        for p in self.parts:
            r = p.record
            if full:
                B = self.base.windowed_regressors(r.u, r.dt, dict(base_nl), slice(0, r.t.size), self.input_range)
                rows.append(np.ascontiguousarray(B[p.rows]))
                fulls.append({name: np.ascontiguousarray(B[:, j]) for j, name in enumerate(self.base_lin)})
            else:  # the model runs over every sample; only the rows are stored
                rows.append(self.base.windowed_regressors(r.u, r.dt, dict(base_nl), p.window, self.input_range))
        cols = _BaseColumns(rows, fulls if full else None)
        for k in list(self._columns):  # keep full columns for one set only (memory)
            if self._columns[k].full is not None and full:
                self._columns[k].full = None
        self._columns[key] = cols
        while len(self._columns) > 4:
            self._columns.pop(next(iter(self._columns)))
        return cols

    def design(self, model: HysteresisModel, nonlinear: Mapping[str, float], only_extra: bool = False,
               parts: Sequence[int] | None = None) -> np.ndarray:
        """Stacked regressor rows (N, n) for the given nonlinear parameters (base's and components'): every linear
        column in ``model.linear_names`` order, or with ``only_extra`` only the columns the components add (for
        components that leave the base's columns unchanged); ``parts``: these records' rows only (default: all)."""
        parts = range(len(self.parts)) if parts is None else parts
        base_nl = {k: nonlinear[k] for k in self.base_nl_names}
        if not isinstance(model, ExtendedModel):
            return np.concatenate([self.base_columns(base_nl).rows[m] for m in parts])
        names = [c for c in model.linear_names if not (only_extra and c in self.base_lin)]
        late = any(CAUSES[c].late_input for c in model.components)
        transforms = any(CAUSES[c].transforms for c in model.components)  # changes the base's columns
        bc = None if late else self.base_columns(base_nl, full=transforms)
        out = np.empty((sum(self.parts[m].rows.size for m in parts), len(names)), order="F")  # QR takes F order
        a = 0
        for m in parts:
            p, r = self.parts[m], self.parts[m].record
            if late:  # the model keeps what a delay and base parameters seen before give (``_late_cache``)
                B = model.windowed_regressors(r.u, r.dt, dict(nonlinear), p.window, self.input_range,
                                              cache=self._late_cache[m])
                cols = {c: B[:, j] for j, c in enumerate(model.linear_names)}
            else:
                cache = self._relaxation_cache[m]
                if len(cache) > RELAXATION_CACHE:
                    cache.clear()
                cols = {c: bc.rows[m][:, j] for j, c in enumerate(self.base_lin)}
                cols.update(model.assemble_columns(r.u, r.dt, bc.full[m] if transforms else {}, nonlinear,
                                                   rows=p.rows, relaxation_cache=cache))
                for c in model.components:  # columns a cause computes on the rows alone (``Cause.row_columns``)
                    cols.update(CAUSES[c].row_columns(nonlinear, r.dt, p.rows))
            for j, c in enumerate(names):
                out[a:a + p.rows.size, j] = cols[c]
            a += p.rows.size
        return out

    solve = staticmethod(solve_scaled)

    def evaluate(self, model: HysteresisModel, nonlinear: Mapping[str, float],
                 full: bool = False) -> tuple[float, np.ndarray | None, np.ndarray]:
        """(rss, theta, residual) with the linear parameters solved. Without ``full``, components that only add
        columns are evaluated against the null (``_against_null``; theta is None)."""
        null = getattr(self, "null", None)
        fixed = null is not None and all(float(nonlinear[k]) == null.params[k] for k in self.base_nl_names)
        if (full or not fixed or not isinstance(model, ExtendedModel)
                or any(CAUSES[c].transforms for c in model.components)):
            theta, res = self.solve(self.design(model, nonlinear), self.y)
            return float(res @ res), theta, res
        return self._against_null(self.design(model, nonlinear, only_extra=True))

    def _against_null(self, E: np.ndarray) -> tuple[float, None, np.ndarray]:
        """Columns E projected off the base's (at the null's parameters) and regressed on the null's residual."""
        E = E - self._q0 @ (self._q0.T @ E)
        c, _ = self.solve(E, self.null_residual)
        res = self.null_residual - E @ c
        return float(res @ res), None, res

    def _fit_null(self, start: Mapping[str, float]) -> Candidate:
        """The base alone, its nonlinear parameters refined on the whole-record rows."""
        z = self.refine(self.base, dict(start), [(n, False) for n in self.base_nl_names]) if self.base_nl_names else {}
        rss, theta, res = self.evaluate(self.base, z, full=True)
        params = {**z, **dict(zip(self.base_lin, map(float, theta)))}
        starts = np.cumsum([0] + [p.rows.size for p in self.parts])
        self.n_effective = effective_sample_size([res[a:b] for a, b in zip(starts[:-1], starts[1:])])
        c = Candidate("none", "base model alone", self.base, params, len(self.base.param_names), rss, self.n,
                      n_effective=self.n_effective)
        c.delta_bic, c.explained = 0.0, 0.0
        self._q0 = column_basis(np.concatenate(self.base_columns(z).rows))  # the base's columns on these rows
        self.null_residual = res
        full = self.base_columns(z, full=True).full
        self._null_prediction = [sum(theta[j] * f[name] for j, name in enumerate(self.base_lin)) for f in full]
        self._null_rest = [float(self.base.simulate(p.record.u[:1], p.record.dt, params, input_range=self.input_range)[0])
                           for p in self.parts]  # a late actuator's output before it starts, per record
        self._null_offset = float(params.get("offset", 0.0))
        self.base_nl = dict(z)
        return c

    def candidate(self, cause: str, label: str, model: HysteresisModel, nonlinear: Mapping[str, float],
                  hyper: dict | None = None, stage: str = "fixed base") -> Candidate:
        nonlinear = {**self.base_nl, **dict(nonlinear)}
        rss, theta, _ = self.evaluate(model, nonlinear, full=True)
        params = {**nonlinear, **dict(zip(model.linear_names, map(float, theta)))}
        c = Candidate(cause, label, model, params, model.n_params, rss, self.n,
                      estimates_of(cause, params, model), n_effective=self.n_effective,
                      hyperparameters=dict(hyper or {}), stage=stage)
        return self._finish(c)

    def _finish(self, c: Candidate) -> Candidate:
        c.delta_bic = c.bic - self.null.bic
        c.explained = 1.0 - c.rss / self.null.rss
        c.limit = self.limit_of(c.cause, c.estimates)
        return c

    def limit_of(self, cause: str, estimates: Mapping) -> str:
        """Why estimates fall outside the cause's meaning (``Cause.limit``): a fit pinned there is not named."""
        return CAUSES[cause].limit(self, estimates) if cause in CAUSES else ""

    def refine(self, model: HysteresisModel, start: Mapping[str, float], free: Sequence[tuple[str, bool]],
               max_nfev: int = 40, residual: Callable | None = None) -> dict:
        """Bounded local least squares over the named nonlinear parameters (log scale where flagged);
        the others stay at ``start`` (the base's, when not named, at the null's)."""
        start = {**getattr(self, "base_nl", {}), **dict(start)}
        box = []  # (lower bound, upper bound, start) per free parameter, on its search scale
        for name, log in free:
            a, b = self.bounds_of(model, name)
            v = min(max(float(start[name]), a), b)
            box.append((math.log(max(a, 1e-12)), math.log(b), math.log(max(v, 1e-12))) if log else (a, b, v))
        lo, hi, x0 = (np.array(column) for column in zip(*box))
        width = np.where(hi > lo, hi - lo, 1.0)
        x0 = np.clip(x0, lo + 1e-9 * width, hi - 1e-9 * width)

        def unpack(x):
            z = dict(start)
            for (name, log), v in zip(free, x):
                z[name] = math.exp(v) if log else float(v)
            return z

        def fun(x):
            return residual(unpack(x)) if residual else self.evaluate(model, unpack(x))[2]

        res = least_squares(fun, x0, bounds=(lo, hi), method="trf", diff_step=1e-4, x_scale=width,
                            max_nfev=max_nfev, ftol=1e-8, xtol=1e-8)
        return unpack(res.x)

    def line_search(self, model: ExtendedModel, name: str, grid: Sequence[float], log: bool = False) -> dict:
        """One nonlinear parameter: the best grid point, then Brent's bounded search between its neighbours."""
        fixed = dict(self.base_nl)
        grid = np.asarray(sorted(grid), dtype=float)

        def rss(v):
            return self.evaluate(model, {**fixed, name: float(v)})[0]

        vals = [rss(g) for g in grid]
        i = int(np.argmin(vals))
        a, b = grid[max(i - 1, 0)], grid[min(i + 1, grid.size - 1)]
        if b > a:
            if log:
                res = minimize_scalar(lambda x: rss(math.exp(x)), bounds=(math.log(a), math.log(b)), method="bounded",
                                      options={"xatol": 1e-3})
                v = math.exp(res.x)
            else:
                res = minimize_scalar(rss, bounds=(a, b), method="bounded", options={"xatol": 2e-3 * (b - a)})
                v = float(res.x)
            if res.fun < vals[i]:
                return {**fixed, name: v}
        return {**fixed, name: float(grid[i])}

    def grid(self, model: ExtendedModel, points: Sequence[Mapping[str, float]]) -> tuple[dict, float]:
        best, best_rss = None, math.inf
        for z in points:
            z = {**self.base_nl, **dict(z)}
            rss = self.evaluate(model, z)[0]
            if rss < best_rss:
                best, best_rss = z, rss
        return best, best_rss

    def promising(self, rss: float) -> bool:
        """Whether a first-order fit explains at least the policy's ``min_explained`` of the null's sum of squares
        (in sample; only a gate for the costlier exact search)."""
        return rss < (1.0 - self.policy.min_explained) * self.null.rss

    @property
    def small(self) -> bool:
        """Records short enough for exact coarse grids of the transforming causes (delay, resonance)."""
        return sum(p.record.t.size for p in self.parts) <= EXACT_GRID_SAMPLES

    def first_order(self, column_of) -> tuple[float, None, np.ndarray]:
        """A transforming component to first order: y ~ B theta + alpha * (T[y0] - y0), y0 the null's
        prediction; ``column_of(m)`` gives T[y0] - y0 on record m's screen rows. Evaluated against the null."""
        return self._against_null(np.concatenate([column_of(m) for m in range(len(self.parts))])[:, None])

    def null_residuals(self) -> list[RecordResidual]:
        """The null's residual over every identification record, whole length."""
        return [RecordResidual(p.record, self._null_prediction[m]) for m, p in enumerate(self.parts)]

    def joint(self, c: Candidate, max_nfev: int = 15) -> Candidate:
        """Refine a stage-1 candidate with the base's nonlinear parameters free too (a separable cause's: a clip
        and a line have their own, ``Cause.joint``)."""
        if not self.base_nl_names or not c.kind.separable:
            return c
        model = c.model
        nl = list(model.nonlinear_names)
        free = [(n, is_log(n)) for n in nl if refined(n)]
        start = {n: c.params[n] for n in nl}
        z = self.refine(model, start, free, max_nfev=max_nfev)
        out = self.candidate(c.cause, c.label, model, z, c.hyperparameters, stage="joint")
        return out if out.rss <= c.rss else c

    def composite(self, primary: Candidate, other: Candidate, search: bool = False) -> Candidate | None:
        return composite(self, primary, other, search=search)
