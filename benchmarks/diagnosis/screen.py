"""The candidate screen: the base model alone (the null) and each cause's extension on a fixed row subset.

Everything here works on the identification records over their WHOLE
length (not only the scored windows), on a fixed random subset of at most
``max_rows`` samples per record (the models still run over every sample;
the subset only makes the least-squares solves small). Linear parameters
are solved exactly at every step (separable least squares).

* The null: the base model alone, its nonlinear parameters refined on these
  rows (from the base fit on the windows), its linear ones solved.
* Stage 1 (the cause modules ``relaxation``, ``delay``, ``resonance``,
  ``creep``, ``interference``, ``saturation``): each cause's extension
  (``hysbench.models.extended``) with the base's nonlinear parameters held
  at the null's. Components that only add columns are regressed on the
  null's residual after projecting off the base's columns.
* Stage 2 (``Screen.joint``): a candidate refined with the base's nonlinear
  parameters free as well (every column recomputed).
* A candidate whose parameters leave the cause's meaning is scored but not
  named (``Screen.limit_of``): a resonance must be underdamped (a mode),
  creep slower than twice the longest drive period.

The screen's internal comparisons use BIC with the AR(1) effective sample
size of the null's residual (``candidates``); the cause is chosen on
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
from hysbench.identification.linear import scaled_lstsq
from hysbench.models import ExtendedModel
from hysbench.models.base import DataScale, HysteresisModel
from hysbench.models.extended import CREEP_TIME_BOUNDS, RESONANCE_HZ_BOUNDS

from .candidates import DRIVE_LOCKED, MAX_ROWS, NO_CUT, Candidate, estimates_of, is_log
from .policy import Policy
from .residuals import RecordResidual, harmonic_phase_turn

EXACT_GRID_SAMPLES = 300_000
COMPOSITE_GRID = 12  # starts per own parameter of a cause searched on top of another (``composite``)
RELAXATION_CACHE = 512  # filtered input rows kept per record (at 10,000 rows: 40 MB per record)


def beyond_others(inputs: Sequence[np.ndarray]) -> list[float]:
    """How far each record's input goes beyond the range of the other records' inputs (either end), as a share
    of the span of them all (0 if within)."""
    if len(inputs) < 2:
        return [0.0] * len(inputs)
    lo, hi = [float(np.min(u)) for u in inputs], [float(np.max(u)) for u in inputs]
    span = max(hi) - min(lo)
    if not span > 0:
        return [0.0] * len(inputs)
    out = []
    for m in range(len(inputs)):
        other_lo = min(v for k, v in enumerate(lo) if k != m)
        other_hi = max(v for k, v in enumerate(hi) if k != m)
        out.append(max(hi[m] - other_hi, other_lo - lo[m], 0.0) / span)
    return out


def first_excursion(u: np.ndarray, lo: float, hi: float, margin: float) -> int | None:
    """The first sample of ``u`` beyond [lo - margin, hi + margin] (None if none is)."""
    beyond = np.flatnonzero((u > hi + margin) | (u < lo - margin))
    return int(beyond[0]) if beyond.size else None


def held_out_windows(inputs: Sequence[np.ndarray], beyond_range: float) -> list[int]:
    """How many samples of each record, from its start, the held-out test predicts (``selection.Folds``):
    all of a record whose input stays within the other records' range (to ``beyond_range`` of the span,
    policy ``beyond_range``), and
    of one that leaves it, the samples before it first does. Fitted on the others, the base model would
    extrapolate beyond (weights of its hysteresis operators that only that record moves), and the comparison
    would measure that, not the cause. The record still takes part whole in every other fold's fit. All
    records are predicted whole if fewer than two stay within."""
    sizes = [int(u.size) for u in inputs]
    beyond = beyond_others(inputs)
    if sum(b <= beyond_range for b in beyond) < 2:
        return sizes
    lo, hi = [float(np.min(u)) for u in inputs], [float(np.max(u)) for u in inputs]
    margin = beyond_range * (max(hi) - min(lo))
    out = []
    for m, u in enumerate(inputs):
        k = None
        if beyond[m] > beyond_range:
            others = [j for j in range(len(inputs)) if j != m]
            k = first_excursion(u, min(lo[j] for j in others), max(hi[j] for j in others), margin)
        out.append(sizes[m] if k is None else k)
    return out


def lag_shared(z: Mapping[str, float]) -> dict:
    """A mode's start on top of a kept delay, the delay shortened by the mode's low-frequency lag
    (2 zeta / omega_n = zeta / (pi f_n)): a delay fitted first has taken up that lag, so with it held a mode
    at its true values adds the lag twice and predicts worse than none."""
    lag = z["damping_ratio"] / (math.pi * z["natural_frequency"])
    return {**z, "delay": max(float(z["delay"]) - lag, 0.0)}


@dataclass
class _Part:
    """One identification record in the screen: its row subset and the base's columns."""

    record: Record
    rows: np.ndarray
    y_rows: np.ndarray


@dataclass
class _BaseColumns:
    """The base's regressor columns for one nonlinear parameter set, per record."""

    rows: list  # (n_rows_m, n_base_linear) per record
    full: list | None  # {name: full-length column} per record, or None if not kept


def solve_scaled(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Column-scaled least squares (minimum norm below 1e-10 of the largest singular value): (theta, residual)."""
    theta = scaled_lstsq(A, y, rcond=1e-10)
    return theta, y - A @ theta


def column_basis(A: np.ndarray) -> np.ndarray:
    """An orthonormal basis of A's column space (columns scaled to unit norm; singular values below 1e-10 of
    the largest dropped)."""
    d = np.sqrt(np.einsum("ij,ij->j", A, A))
    d[~(d > 0)] = 1.0
    u_, s_, _ = np.linalg.svd(A / d, full_matrices=False)
    return np.ascontiguousarray(u_[:, s_ > 1e-10 * s_[0]])


class Screen:
    """The candidate fits on a fixed row subset of the identification records.

    Stage 1: each cause's extension with the base's nonlinear
    parameters held at the null's; only the components' columns are new, so
    they are projected off the base's columns and regressed on the null's
    residual (cheap). Stage 2 (``joint``): a candidate refined with the
    base's nonlinear parameters free as well (every column recomputed). ``policy``: the decision policy
    (``policy.Policy``), carried for every step that works on the screen.
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
            self.parts.append(_Part(r, rows, r.y[rows].copy()))
        self._relaxation_cache = [{} for _ in self.parts]  # {(tau, power): filtered input at the rows} per record
        self.y = np.concatenate([p.y_rows for p in self.parts])
        self.n = self.y.size
        inputs = [p.record.u for p in self.parts]
        windows = held_out_windows(inputs, policy.beyond_range)
        self.scored_rows = [int(np.searchsorted(p.rows, w)) for p, w in zip(self.parts, windows)]  # predicted rows
        self.held_out_windows = windows  # per record: samples predicted from its start
        self.beyond_range = beyond_others(inputs)
        self.n_held_out_rows = sum(self.scored_rows)
        # the causes' time scale
        self.drive_time = min(shortest_period(p.record.u, p.record.dt, p.record.frequency_hz) for p in self.parts)
        self.component_scale = replace(scale, time=self.drive_time)
        # the lowest natural frequency a mode is searched at: 1 / the shortest drive period, or lower, down to
        # the low end of the band of a record without a nominal frequency (a broadband drive excites a mode
        # inside its band, where it shows best)
        bands = [drive_band(p.record.u, p.record.dt) for p in self.parts if not p.record.frequency_hz]
        self.mode_floor = min([RESONANCE_HZ_BOUNDS[0] / self.drive_time, *(b[0] for b in bands if b is not None)])
        self._extension_cache: dict = {}
        self._columns: dict = {}  # base nonlinear tuple -> _BaseColumns (a few, most recent last)
        self.n_evaluations = 0
        start = {k: float(base_params[k]) for k in self.base_nl_names}
        self.null = self._fit_null(start)

    # --- models ------------------------------------------------------------
    def extension(self, components: Sequence[str], **hyper) -> ExtendedModel:
        key = (tuple(components), tuple(sorted((k, tuple(v) if isinstance(v, list) else v) for k, v in hyper.items())))
        m = self._extension_cache.get(key)
        if m is None:
            m = ExtendedModel(base=self.base.name, components=tuple(components),
                              base_hyperparameters=self.base.get_hyperparameters(), **hyper)
            self._extension_cache[key] = m
        return m

    @property
    def held_out(self) -> list[bool]:
        """Per record: a held-out target (some of its rows predicted)."""
        return [k > 0 for k in self.scored_rows]

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
                if name == "creep_time":
                    return max(float(p.min), self.creep_min), float(p.max)
                if name == "damping_ratio":  # a resonance is a mode: underdamped
                    return float(p.min), min(float(p.max), self.policy.max_damping)
                if name == "natural_frequency":  # down to a broadband drive's band; nothing above Nyquist
                    return min(float(p.min), self.mode_floor), min(float(p.max), self.nyquist)
                if name == "interference_frequency":  # the samples show nothing faster
                    return float(p.min), min(float(p.max), self.nyquist)
                return float(p.min), float(p.max)
        raise KeyError(name)

    @property
    def nyquist(self) -> float:
        """The Nyquist frequency (Hz) of the most coarsely sampled record."""
        return 0.5 / max(p.record.dt for p in self.parts)

    # --- the base's columns ---------------------------------------------------
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
                rows.append(self.base.windowed_regressors(r.u, r.dt, dict(base_nl), p.rows, self.input_range))
        cols = _BaseColumns(rows, fulls if full else None)
        for k in list(self._columns):  # keep full columns for one set only (memory)
            if self._columns[k].full is not None and full:
                self._columns[k].full = None
        self._columns[key] = cols
        while len(self._columns) > 4:
            self._columns.pop(next(iter(self._columns)))
        return cols

    # --- linear solves -----------------------------------------------------
    @staticmethod
    def transforms(model: HysteresisModel) -> bool:
        """Whether the model's components change the base's columns (resonance, delay)."""
        return isinstance(model, ExtendedModel) and (model.has("resonance") or model.has("delay"))

    def design(self, model: HysteresisModel, nonlinear: Mapping[str, float], only_extra: bool = False) -> np.ndarray:
        """Stacked regressor rows (N, n) for the given nonlinear parameters (base's and components'):
        every linear column in ``model.linear_names`` order, or with ``only_extra`` only the
        columns the components add (for components that leave the base's columns unchanged)."""
        base_nl = {k: nonlinear[k] for k in self.base_nl_names}
        names = [c for c in model.linear_names if not (only_extra and c in self.base_lin)]
        if isinstance(model, ExtendedModel) and model.has("delay"):  # the base runs on a late input
            cols = [model.linear_names.index(c) for c in names]
            return np.concatenate([model.windowed_regressors(p.record.u, p.record.dt, dict(nonlinear), p.rows,
                                                             self.input_range)[:, cols] for p in self.parts])
        transforms = self.transforms(model)
        bc = self.base_columns(base_nl, full=transforms)
        if not isinstance(model, ExtendedModel):
            return np.concatenate(bc.rows)
        blocks = []
        for m, p in enumerate(self.parts):
            r = p.record
            cache = self._relaxation_cache[m]
            if len(cache) > RELAXATION_CACHE:
                cache.clear()
            cols = model.assemble_columns(r.u, r.dt, bc.full[m] if transforms else {}, nonlinear, rows=p.rows,
                                          relaxation_cache=cache)
            out = np.empty((p.rows.size, len(names)), order="F")  # filled by column; QR takes Fortran order
            for j, c in enumerate(names):
                if c in ("interference_sin", "interference_cos"):  # on the rows only
                    phase = 2.0 * np.pi * nonlinear["interference_frequency"] * r.dt * p.rows
                    out[:, j] = np.sin(phase) if c == "interference_sin" else np.cos(phase)
                else:
                    out[:, j] = bc.rows[m][:, self.base_lin.index(c)] if c not in cols else cols[c]
            blocks.append(out)
        return np.concatenate(blocks)

    @staticmethod
    def solve(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return solve_scaled(A, y)

    def evaluate(self, model: HysteresisModel, nonlinear: Mapping[str, float],
                 full: bool = False) -> tuple[float, np.ndarray | None, np.ndarray]:
        """(rss, theta, residual) with the linear parameters solved. Without ``full``, components that
        only add columns are evaluated against the null (their columns projected off the base's at
        the null's nonlinear parameters, regressed on its residual; theta is None)."""
        self.n_evaluations += 1
        null = getattr(self, "null", None)
        fixed = null is not None and all(float(nonlinear[k]) == null.params[k] for k in self.base_nl_names)
        if full or self.transforms(model) or not fixed or not isinstance(model, ExtendedModel):
            theta, res = self.solve(self.design(model, nonlinear), self.y)
            return float(res @ res), theta, res
        E = self.design(model, nonlinear, only_extra=True)
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
                      hyperparameters=dict(hyper or {}))
        c.stage = stage
        return self._finish(c)

    def _finish(self, c: Candidate) -> Candidate:
        c.delta_bic = c.bic - self.null.bic
        c.explained = 1.0 - c.rss / self.null.rss
        c.limit = self.limit_of(c.cause, c.estimates)
        return c

    def limit_of(self, cause: str, estimates: Mapping) -> str:
        """Why estimates fall outside the cause's meaning: a resonance must be a mode (underdamped),
        creep slower than the drive, a delay at least one sample long; a fit pinned at those limits is not
        named."""
        pol = self.policy
        if cause == "resonance" and estimates["damping_ratio"] >= pol.damping_limit_share * pol.max_damping:
            return f"damping ratio at the limit {pol.max_damping:g}: no mode"
        if cause == "relaxation":
            taus = estimates["tau_s"]
            if any(b < pol.duplicate_tau_ratio * a for a, b in zip(taus, taus[1:])):
                return (f"time constants closer than a factor {pol.duplicate_tau_ratio:g}: their difference is a "
                        "band-pass, not a relaxation")
        if cause == "interference" and estimates["frequency_hz"] * self.shortest_span < pol.interference_min_cycles:
            return (f"fewer than {pol.interference_min_cycles:g} cycles in the shortest record "
                    f"({self.shortest_span:.3g} s): with its phase free per record, a slower sinusoid is a per-record drift, not a disturbance")
        if cause == "interference" and self.drive_locked(estimates):
            return DRIVE_LOCKED
        if cause == "saturation" and "slope_where_clipped" not in estimates:  # the level cuts (almost) nothing
            return NO_CUT
        if cause == "saturation" and abs(estimates["slope_where_clipped"]) >= pol.max_clipped_slope:
            moves = "rises with" if estimates["slope_where_clipped"] > 0 else "moves against"
            return (f"where it would clip, the output still {moves} the model (slope "
                    f"{estimates['slope_where_clipped']:.2f}; a clip leaves it flat): not a clip")
        if cause == "delay" and estimates["delay_s"] < (dt := max(p.record.dt for p in self.parts)):
            return (f"shorter than one sample ({1e3 * dt:.3g} ms): an input late by less than a sample is the input "
                    "plus a first difference of it (a rate term), not a resolved delay")
        if cause == "creep" and estimates["time_scale_s"] <= pol.creep_limit_margin * self.creep_min:
            return f"time scale at the limit {self.creep_min:.3g} s ({pol.creep_periods:g} drive periods): not slow"
        return ""

    # --- nonlinear search --------------------------------------------------
    def refine(self, model: HysteresisModel, start: Mapping[str, float], free: Sequence[tuple[str, bool]],
               max_nfev: int = 40, residual: Callable | None = None) -> dict:
        """Bounded local least squares over the named nonlinear parameters (log scale where flagged);
        the others stay at ``start`` (the base's, when not named, at the null's)."""
        start = {**getattr(self, "base_nl", {}), **dict(start)}
        lo, hi, x0 = [], [], []
        for name, log in free:
            a, b = self.bounds_of(model, name)
            v = min(max(float(start[name]), a), b)
            if log:
                a, b, v = math.log(max(a, 1e-12)), math.log(b), math.log(max(v, 1e-12))
            lo.append(a)
            hi.append(b)
            x0.append(v)
        lo, hi, x0 = np.array(lo), np.array(hi), np.array(x0)
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

    def line_search(self, model: ExtendedModel, name: str, grid: Sequence[float], log: bool = False,
                    fixed: Mapping[str, float] | None = None, evaluate: Callable | None = None) -> dict:
        """One nonlinear parameter: the best grid point, then Brent's bounded search between its neighbours."""
        fixed = {**self.base_nl, **dict(fixed or {})}
        grid = np.asarray(sorted(grid), dtype=float)
        evaluate = evaluate or (lambda z: self.evaluate(model, z))

        def rss(v):
            return evaluate({**fixed, name: float(v)})[0]

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
        E = np.concatenate([column_of(m) for m in range(len(self.parts))])[:, None]
        E = E - self._q0 @ (self._q0.T @ E)
        c, _ = self.solve(E, self.null_residual)
        res = self.null_residual - E @ c
        self.n_evaluations += 1
        return float(res @ res), None, res

    def null_residuals(self) -> list[RecordResidual]:
        """The null's residual over every identification record, whole length."""
        return [RecordResidual(p.record, self._null_prediction[m]) for m, p in enumerate(self.parts)]

    def drive_locked(self, estimates: Mapping) -> bool:
        """A sinusoid within the spectral resolution (half a cycle over the longest record) of a harmonic of
        every record's drive whose phases in the records (each from its own start) agree within
        ``locked_phase`` rad, and which does not turn in phase from one drive period to the next (in the base
        model's residual, at the harmonic; ``residuals.harmonic_phase_turn``): a turn of more than
        ``locked_turn`` rad per period and ``locked_turn_z`` standard errors (policy fields) is a line off the
        harmonic, closer
        to it than the records resolve, not a misfit that the drive repeats."""
        phases = estimates.get("phase_rad_per_record") or []
        longest = max(p.record.t.size * p.record.dt for p in self.parts)
        if len(phases) < 2 or not self.drive_harmonic(np.array([estimates["frequency_hz"]]), 0.5 / longest)[0]:
            return False
        spread = max(abs(math.remainder(a - b, 2 * math.pi)) for i, a in enumerate(phases) for b in phases[i + 1:])
        pol = self.policy
        if spread >= pol.locked_phase:
            return False
        turn = harmonic_phase_turn(self.null_residuals(), estimates["frequency_hz"])
        return turn is None or not (abs(turn[0]) > pol.locked_turn and abs(turn[0]) > pol.locked_turn_z * turn[1])

    def drive_harmonic(self, f: np.ndarray, tolerance_hz: float) -> np.ndarray:
        """Whether each frequency is a harmonic of every identification record's drive (within tolerance):
        there a disturbance cannot be told from the model's misfit."""
        out = np.ones(f.shape, dtype=bool)
        for p in self.parts:
            fd = p.record.frequency_hz
            if not fd:
                return np.zeros(f.shape, dtype=bool)
            k = np.maximum(np.round(f / fd), 1.0)
            out &= np.abs(f - k * fd) <= tolerance_hz
        return out

    # --- stage 2: the base's nonlinear parameters free as well --------------------
    def joint(self, c: Candidate, max_nfev: int = 15) -> Candidate:
        """Refine a stage-1 candidate with the base's nonlinear parameters free too (not saturation:
        ``saturation.joint_saturation``; not interference: its phase is per record)."""
        if not self.base_nl_names or c.cause in ("saturation", "interference"):
            return c
        model = c.model
        nl = list(model.nonlinear_names)
        free = [(n, is_log(n)) for n in nl if n != "interference_frequency"]
        start = {n: c.params[n] for n in nl}
        z = self.refine(model, start, free, max_nfev=max_nfev)
        out = self.candidate(c.cause, c.label, model, z, c.hyperparameters, stage="joint")
        return out if out.rss <= c.rss else c

    # --- composite (secondary causes) ---------------------------------------------
    def composite(self, primary: Candidate, other: Candidate, max_nfev: int = 10,
                  search: bool = False) -> Candidate | None:
        """The primary's extension (itself possibly a composite) plus another cause, refined from both fits
        (separable causes only). With ``search`` the other cause's own parameters are also started from a
        coarse grid over their search bounds (the primary held): its fit against the base alone can be far
        off when the base misses something larger; the best start is refined only if it removes at least
        the policy's ``min_explained`` of the primary's sum of squares (else None: nothing to add, and a refinement with
        every nonlinear parameter free is the costly part)."""
        parts = tuple(getattr(primary.model, "components", (primary.cause,)))
        if {"saturation", "interference"} & {*parts, other.cause} or other.cause in parts:
            return None
        hyper = {**primary.hyperparameters, **other.hyperparameters}
        model = self.extension((*parts, other.cause), **hyper)
        start = {n: primary.params.get(n, other.params.get(n)) for n in model.nonlinear_names}
        if search:
            starts = self._starts(model, start, [n for n in model.nonlinear_names if n not in primary.params])
            if other.cause == "resonance" and "delay" in primary.params:
                starts += [lag_shared(q) for q in starts[1:]]
            rss = [self.evaluate(model, z)[0] for z in starts]
            if min(rss) > (1.0 - self.policy.min_explained) * primary.rss:
                return None
            start = starts[int(np.argmin(rss))]
        free = [(n, is_log(n)) for n in model.nonlinear_names if n != "interference_frequency"]
        z = self.refine(model, start, free, max_nfev=max_nfev) if free else start
        c = self.candidate(other.cause, f"{primary.label} + {other.label}", model, z, hyper, stage="joint")
        c.estimates = estimates_of(other.cause, c.params, model)
        c.delta_bic = c.bic - primary.bic  # against the primary alone
        c.explained = 1.0 - c.rss / primary.rss
        c.limit = self.limit_of(other.cause, c.estimates)
        return c

    def _starts(self, model: HysteresisModel, start: Mapping[str, float], names: Sequence[str]) -> list[dict]:
        """``start`` and a grid over the named parameters' search bounds (geometric for log-scale ones):
        ``COMPOSITE_GRID`` points for one parameter, ``COMPOSITE_GRID // 2`` per axis for two (a mode's
        frequency and damping); a relaxation of several time constants keeps its own start."""
        if not names or (len(names) > 1 and any(n.startswith("tau") for n in names)):  # several time constants
            return [dict(start)]
        k = max(3, COMPOSITE_GRID // len(names))
        axes = []
        for n in names:
            lo, hi = self.bounds_of(model, n)
            if n == "delay":
                lo = min(p.record.dt for p in self.parts)
            if not hi > lo:  # nothing to search
                return [dict(start)]
            # inside the bounds (a start at a bound is a bound estimate if nothing moves it)
            spaced = np.geomspace if is_log(n) or n == "delay" else np.linspace
            axes.append(spaced(lo, hi, k + 2)[1:-1])
        grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(names))
        return [dict(start)] + [{**start, **dict(zip(names, map(float, g)))} for g in grid]
