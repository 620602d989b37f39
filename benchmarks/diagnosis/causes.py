"""Candidate causes of a model's misfit: a sparse library screen and explicit fits of each extension.

Everything here works on the identification records over their WHOLE
length (not only the scored windows), on a fixed random subset of at most
``max_rows`` samples per record (the models still run over every sample;
the subset only makes the least-squares solves small). Every row has the
same weight, so the sum of squares is a Gaussian log-likelihood and

    BIC = N ln(RSS / N) + k ln N

(N rows, k free parameters) compares candidates that are not nested.
Linear parameters are solved exactly at every step (separable least squares).

* The null: the base model alone, its nonlinear parameters refined on these
  rows (from the base fit on the windows), its linear ones solved.
* Library screen (pysindy): the null's residual regressed, by forward
  orthogonal least squares (``pysindy.FROLS``, number of terms by BIC), on
  a library of candidate terms -- first-order low-pass histories of the
  input on a grid of time constants, the derivatives of the model's own
  output, slow exponential drifts, a sinusoid at the pooled spectrum's
  peak, hinge functions of the model's output at high and low levels --
  each made orthogonal to the base model's regressors and scaled to unit
  norm. The terms it keeps, and the share of the residual each explains,
  are evidence; their time constants seed the relaxation fits.
* Stage 1, explicit fits with the base's nonlinear parameters held at the
  null's: each cause's extension (``hysbench.models.extended``), its own
  nonlinear parameters found by a grid (interference: the peaks of the
  pooled coherent spectrum of the null's residual) and a bounded local
  refinement. Components that only add columns (relaxation, creep,
  interference) are regressed on the null's residual after projecting off
  the base's columns. Delay and resonance change every column: they are
  searched to first order (the null's prediction delayed / filtered, one
  extra column) and, where that passes the threshold, exactly. Saturation
  is fitted as censored regression: for a clipping level, the linear
  parameters are solved on the samples not at the level, and the clipped
  model is scored on all samples; both sides are tried.
* Relaxation is fitted with 1, 2, ... ``max_relaxation`` time constants
  (greedy: each new one by a grid search with the others fixed, then all
  jointly; it stops when one more lowers BIC by less than the threshold);
  the variant with the lowest BIC stands for the cause.
* Stage 2 (``run_screen``): the best candidates (and every relaxation
  variant, when relaxation is among them) are refined with the base's
  nonlinear parameters free as well.
* A candidate whose parameters leave the cause's meaning is scored but not
  named (``Screen.limit_of``): a resonance must be underdamped (a mode),
  creep slower than twice the longest drive period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import least_squares, minimize_scalar

from hysbench.data.dataset import Record
from hysbench.models import ExtendedModel
from hysbench.models.base import DataScale, HysteresisModel
from hysbench.models.extended import (
    CREEP_TIME_BOUNDS,
    DELAY_BOUND,
    RESONANCE_HZ_BOUNDS,
    TAU_BOUNDS,
)
from hysbench.models.filter_kernels import first_order_foh, lowpass1_bank, lowpass2_rows, second_order_foh

from .residuals import RecordResidual, coherent_spectrum, spectral_peaks

MAX_ROWS = 10_000  # rows per record in the screen
MAX_RELAXATION = 4
BIC_THRESHOLD = 10.0  # a cause needs BIC lower than the null's by this much
MIN_EXPLAINED = 0.01  # ... and to explain this share of the null's residual sum of squares
CREEP_PERIODS = 2.0  # creep's time scale is at least this many of the longest drive period
MAX_DAMPING = 1.0  # a resonance (a mode) is underdamped


@dataclass
class Candidate:
    """One fitted candidate: a cause's extension (or the null) on the screen's rows."""

    cause: str
    label: str
    model: HysteresisModel
    params: dict  # every parameter of ``model``
    k: int  # free parameters counted by BIC
    rss: float
    n: int
    estimates: dict = field(default_factory=dict)  # the cause's parameters in report units
    bic: float = math.nan
    delta_bic: float = math.nan  # against the null
    explained: float = math.nan  # share of the null's identification RSS explained
    validation_rss: float = math.nan
    validation_explained: float = math.nan  # share of the null's validation RSS explained (evidence only)
    hyperparameters: dict = field(default_factory=dict)
    stage: str = "joint"  # "fixed base": the base's nonlinear parameters held at the null's
    limit: str = ""  # why the candidate cannot be named (a parameter at the vocabulary's limit), if so

    def __post_init__(self):
        self.bic = bic(self.rss, self.n, self.k)

    def summary(self) -> dict:
        return {"cause": self.cause, "label": self.label, "model": self.model.name, "stage": self.stage,
                "admissible": not self.limit, "limit": self.limit, "k": self.k,
                "bic": self.bic, "delta_bic": self.delta_bic, "rss": self.rss, "n_rows": self.n,
                "explained_identification": self.explained, "explained_validation": self.validation_explained,
                "estimates": self.estimates}


def bic(rss: float, n: int, k: int) -> float:
    return float(n * math.log(max(rss, 1e-300) / n) + k * math.log(n))


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


def estimates_of(cause: str, params: Mapping[str, float], model: HysteresisModel) -> dict:
    """A cause's parameters in the report's vocabulary."""
    if cause == "relaxation":
        k = getattr(model, "n_relaxation", 0)
        taus = sorted(float(params[f"tau{i}"]) for i in range(1, k + 1))
        return {"tau_s": taus}
    if cause == "delay":
        return {"delay_s": float(params["delay"])}
    if cause == "resonance":
        return {"natural_frequency_hz": float(params["natural_frequency"]),
                "damping_ratio": float(params["damping_ratio"])}
    if cause == "creep":
        return {"size": float(params["creep_size"]), "time_scale_s": float(params["creep_time"])}
    if cause == "interference":
        a, b = float(params["interference_sin"]), float(params["interference_cos"])
        return {"frequency_hz": float(params["interference_frequency"]), "amplitude": math.hypot(a, b),
                "phase_rad": math.atan2(b, a)}
    if cause == "saturation":
        return {"level": float(params["saturation_level"]), "side": getattr(model, "saturation_side", "upper")}
    return {}


LOG_SCALE = ("tau", "creep_time", "natural_frequency", "damping_ratio")


def _is_log(name: str) -> bool:
    return any(name.startswith(s) for s in LOG_SCALE)


class Screen:
    """The candidate fits on a fixed row subset of the identification records.

    Stage 1: each cause's extension with the base's nonlinear
    parameters held at the null's; only the components' columns are new, so
    they are projected off the base's columns and regressed on the null's
    residual (cheap). Stage 2 (``joint``): a candidate refined with the
    base's nonlinear parameters free as well (every column recomputed).
    """

    def __init__(self, base: HysteresisModel, base_params: Mapping[str, float], input_range,
                 identification: Sequence[Record], validation: Sequence[Record], scale: DataScale,
                 noise_sd: float, max_rows: int = MAX_ROWS, seed: int = 0):
        self.base = base
        self.input_range = tuple(input_range)
        self.scale = scale
        self.base_nl_names = base.nonlinear_names
        self.base_lin = base.linear_names
        self.validation = list(validation)
        self.noise_sd = float(noise_sd)
        rng = np.random.default_rng(seed)
        self.parts: list[_Part] = []
        for r in identification:
            n = r.t.size
            rows = np.arange(n) if n <= max_rows else np.sort(rng.choice(n, max_rows, replace=False))
            self.parts.append(_Part(r, rows, r.y[rows].copy()))
        self.y = np.concatenate([p.y_rows for p in self.parts])
        self.n = self.y.size
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
    def creep_min(self) -> float:
        """Creep is a drift much slower than the drive: at least twice the longest drive period."""
        periods = [1.0 / p.record.frequency_hz for p in self.parts if p.record.frequency_hz]
        return max(CREEP_TIME_BOUNDS[0] * self.scale.time, CREEP_PERIODS * max(periods, default=0.0))

    def bounds_of(self, model: HysteresisModel, name: str) -> tuple[float, float]:
        for p in model.parameters(self.scale):
            if p.name == name:
                if name == "creep_time":
                    return max(float(p.min), self.creep_min), float(p.max)
                if name == "damping_ratio":  # a resonance is a mode: underdamped
                    return float(p.min), min(float(p.max), MAX_DAMPING)
                return float(p.min), float(p.max)
        raise KeyError(name)

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
            if transforms:
                cols = model.assemble_columns(r.u, r.dt, bc.full[m], nonlinear)
            else:
                cols = model.assemble_columns(r.u, r.dt, {}, nonlinear)
            out = np.empty((p.rows.size, len(names)))
            for j, c in enumerate(names):
                if c in ("interference_sin", "interference_cos"):  # on the rows only
                    phase = 2.0 * np.pi * nonlinear["interference_frequency"] * r.dt * p.rows
                    out[:, j] = np.sin(phase) if c == "interference_sin" else np.cos(phase)
                else:
                    out[:, j] = bc.rows[m][:, self.base_lin.index(c)] if c not in cols else cols[c][p.rows]
            blocks.append(out)
        return np.concatenate(blocks)

    @staticmethod
    def solve(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Least squares with unit-norm columns (SVD, minimum norm): (theta, residual)."""
        d = np.sqrt(np.einsum("ij,ij->j", A, A))
        d[~(d > 0)] = 1.0
        theta = np.linalg.lstsq(A / d, y, rcond=1e-10)[0] / d
        return theta, y - A @ theta

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
        c = Candidate("none", "base model alone", self.base, params, len(self.base.param_names), rss, self.n)
        c.delta_bic, c.explained = 0.0, 0.0
        A = np.concatenate(self.base_columns(z).rows)
        d = np.sqrt(np.einsum("ij,ij->j", A, A))
        d[~(d > 0)] = 1.0
        u_, s_, _ = np.linalg.svd(A / d, full_matrices=False)
        self._q0 = np.ascontiguousarray(u_[:, s_ > 1e-10 * s_[0]])  # basis of the base's columns on these rows
        self.null_residual = res
        full = self.base_columns(z, full=True).full
        self._null_prediction = [sum(theta[j] * f[name] for j, name in enumerate(self.base_lin)) for f in full]
        self._null_rest = float(self.base.simulate(np.zeros(1), self.parts[0].record.dt, params,
                                                   input_range=self.input_range)[0])
        self._null_offset = float(params.get("offset", 0.0))
        self.base_nl = dict(z)
        return c

    def candidate(self, cause: str, label: str, model: HysteresisModel, nonlinear: Mapping[str, float],
                  hyper: dict | None = None, stage: str = "fixed base") -> Candidate:
        nonlinear = {**self.base_nl, **dict(nonlinear)}
        rss, theta, _ = self.evaluate(model, nonlinear, full=True)
        params = {**nonlinear, **dict(zip(model.linear_names, map(float, theta)))}
        c = Candidate(cause, label, model, params, model.n_params, rss, self.n,
                      estimates_of(cause, params, model), hyperparameters=dict(hyper or {}))
        c.stage = stage
        return self._finish(c)

    def _finish(self, c: Candidate) -> Candidate:
        c.delta_bic = c.bic - self.null.bic
        c.explained = 1.0 - c.rss / self.null.rss
        c.limit = self.limit_of(c.cause, c.estimates)
        return c

    def limit_of(self, cause: str, estimates: Mapping) -> str:
        """Why estimates fall outside the cause's meaning: a resonance must be a mode (underdamped),
        creep slower than the drive; a fit pinned at those limits is not named."""
        if cause == "resonance" and estimates["damping_ratio"] >= 0.98 * MAX_DAMPING:
            return f"damping ratio at the limit {MAX_DAMPING:g}: no mode"
        if cause == "creep" and estimates["time_scale_s"] <= 1.02 * self.creep_min:
            return f"time scale at the limit {self.creep_min:.3g} s ({CREEP_PERIODS:g} drive periods): not slow"
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

    # --- stage 1: each cause with the base's nonlinear parameters fixed -------------
    def relaxation(self, max_relaxation: int = MAX_RELAXATION, seeds: Sequence[float] = (),
                   powers: Sequence[int] = (1,), stop_threshold: float = BIC_THRESHOLD) -> list[Candidate]:
        T = self.scale.time
        lo, hi = TAU_BOUNDS[0] * T, TAU_BOUNDS[1] * T
        grid = list(np.exp(np.linspace(math.log(lo), math.log(hi), 25))) + [float(s) for s in seeds if lo <= s <= hi]
        out, taus = [], []
        for k in range(1, max_relaxation + 1):
            model = self.extension(("relaxation",), n_relaxation=k, relaxation_powers=list(powers))
            names = [f"tau{i}" for i in range(1, k + 1)]
            z, _ = self.grid(model, [dict(zip(names, taus + [g])) for g in grid])
            if k > 1:
                z = self.refine(model, z, [(n, True) for n in names])
            else:
                z = self.line_search(model, "tau1", grid, log=True)
            taus = [z[n] for n in names]
            label = f"relaxation, {k} time constant{'s' if k > 1 else ''}"
            out.append(self.candidate("relaxation", label, model, z,
                                      {"n_relaxation": k, "relaxation_powers": list(powers)}))
            if k > 1 and out[-1].bic > out[-2].bic - stop_threshold:  # one more did not help: stop
                break
        return out

    def promising(self, rss: float, k_extra: int) -> bool:
        """Whether a first-order fit with k_extra more parameters than the null passes the BIC threshold."""
        return bic(rss, self.n, self.null.k + k_extra) - self.null.bic < -BIC_THRESHOLD

    def first_order(self, column_of) -> tuple[float, None, np.ndarray]:
        """A transforming component to first order: y ~ B theta + alpha * (T[y0] - y0), y0 the null's
        prediction; ``column_of(m)`` gives T[y0] - y0 on record m's screen rows. Evaluated against the null."""
        E = np.concatenate([column_of(m) for m in range(len(self.parts))])[:, None]
        E = E - self._q0 @ (self._q0.T @ E)
        c, _ = self.solve(E, self.null_residual)
        res = self.null_residual - E @ c
        self.n_evaluations += 1
        return float(res @ res), None, res

    def _delayed_null(self, z):
        def column(m):
            y0, rows = self._null_prediction[m], self.parts[m].rows
            pos = rows - z["delay"] / self.parts[m].record.dt
            return np.interp(pos, np.arange(y0.size), y0, left=self._null_rest) - y0[rows]
        return self.first_order(column)

    def _resonant_null(self, z):
        def column(m):
            y0 = self._null_prediction[m] - self._null_offset
            rows = self.parts[m].rows
            phi, g0, g1 = second_order_foh(z["natural_frequency"], z["damping_ratio"], self.parts[m].record.dt)
            return lowpass2_rows(np.ascontiguousarray(y0[None, :]), phi, g0, g1)[0][rows] - y0[rows]
        return self.first_order(column)

    def delay(self) -> Candidate:
        """Searched to first order (the null's prediction delayed) on a grid of about two samples;
        if that passes the BIC threshold, the best grid points and a one-sample delay are searched
        exactly (Brent within two samples), since a first-order search can be led astray by a misfit
        of another kind; otherwise the first-order optimum is evaluated exactly, once."""
        model = self.extension(("delay",))
        dt = min(p.record.dt for p in self.parts)
        hi = DELAY_BOUND * self.scale.time
        grid = np.linspace(0.0, hi, int(min(max(hi / (2 * dt), 10), 400)) + 1)
        vals = np.array([self._delayed_null({**self.base_nl, "delay": float(d)})[0] for d in grid])
        if not self.promising(float(vals.min()), 2):  # not even to first order: one exact evaluation
            return self.candidate("delay", "pure delay", model, {**self.base_nl, "delay": float(grid[np.argmin(vals)])})
        starts = [float(grid[i]) for i in _local_minima(vals, 2)] + [min(dt, hi)]
        best, best_rss = None, math.inf
        for d0 in starts:
            z = self.line_search(model, "delay", [max(d0 - 2 * dt, 0.0), d0, min(d0 + 2 * dt, hi)])
            rss = self.evaluate(model, z)[0]
            if rss < best_rss:
                best, best_rss = z, rss
        return self.candidate("delay", "pure delay", model, best)

    def resonance(self) -> Candidate:
        """Searched to first order (the null's prediction through the mode) on a grid and refined; if
        that passes the BIC threshold, it and a fast, well-damped mode are evaluated exactly and the
        better refined exactly; otherwise the first-order optimum is evaluated exactly, once."""
        model = self.extension(("resonance",))
        T = self.scale.time
        dt = min(p.record.dt for p in self.parts)
        f_lo = RESONANCE_HZ_BOUNDS[0] / T
        f_hi = min(RESONANCE_HZ_BOUNDS[1] / T, 0.1 / dt)
        fs = np.exp(np.linspace(math.log(f_lo * 1.2), math.log(f_hi), 9))
        pts = [{**self.base_nl, "natural_frequency": float(f), "damping_ratio": zeta} for f in fs
               for zeta in (0.07, 0.25, 0.8)]
        vals = np.array([self._resonant_null(z)[0] for z in pts])
        starts = []
        z = self.refine(model, pts[int(np.argmin(vals))], [("natural_frequency", True), ("damping_ratio", True)],
                        max_nfev=12, residual=lambda q: self._resonant_null(q)[2])
        z = {**z, "damping_ratio": min(z["damping_ratio"], MAX_DAMPING)}
        if not self.promising(self._resonant_null(z)[0], 3):  # not even to first order: one exact evaluation
            return self.candidate("resonance", "second-order mode", model, z)
        starts.append(z)
        starts.append({**self.base_nl, "natural_frequency": float(fs[-1]), "damping_ratio": 0.7})
        starts = [{**q, "damping_ratio": min(q["damping_ratio"], MAX_DAMPING)} for q in starts]
        z = min(starts, key=lambda q: self.evaluate(model, q)[0])
        z = self.refine(model, z, [("natural_frequency", True), ("damping_ratio", True)], max_nfev=6)
        return self.candidate("resonance", "second-order mode", model, z)

    def creep(self) -> Candidate:
        model = self.extension(("creep",))
        lo, hi = self.bounds_of(model, "creep_time")
        z = self.line_search(model, "creep_time", np.exp(np.linspace(math.log(lo), math.log(hi), 17)), log=True)
        return self.candidate("creep", "slow drift since the start", model, z)

    def null_residuals(self) -> list[RecordResidual]:
        """The null's residual over every identification record, whole length."""
        return [RecordResidual(p.record, self._null_prediction[m]) for m, p in enumerate(self.parts)]

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

    def interference(self, n_peaks: int = 5) -> Candidate:
        """Candidate frequencies: the most prominent peaks of the pooled coherent spectrum of the
        null's residual (amplitude over its running median), harmonics common to every drive left
        out; each refined by a line search."""
        model = self.extension(("interference",))
        lo, hi = self.bounds_of(model, "interference_frequency")
        hi = min(hi, 0.45 / max(p.record.dt for p in self.parts))  # below every record's Nyquist frequency
        f, amp = coherent_spectrum(self.null_residuals(), lo, hi)
        prom = prominence(amp)
        prom[self.drive_harmonic(f, 2.0 * (f[1] - f[0]) if f.size > 1 else 0.0)] = 0.0
        peaks = spectral_peaks(f, prom, n=n_peaks, min_separation_hz=max(lo, 0.05))
        step = 1.0 / max(p.record.t.size * p.record.dt for p in self.parts)  # the longest record's resolution
        best, best_rss = {**self.base_nl, "interference_frequency": float(min(max(10.0, lo), hi))}, math.inf
        for f0, _ in peaks:
            grid = [g for g in f0 + step * np.linspace(-1.0, 1.0, 21) if lo <= g <= hi]
            if not grid:
                continue
            z = self.line_search(model, "interference_frequency", grid)
            rss = self.evaluate(model, z)[0]
            if rss < best_rss:
                best, best_rss = z, rss
        return self.candidate("interference", "sinusoidal disturbance", model, best)

    def saturation_rss(self, side: str, level: float, base_nl: Mapping[str, float],
                       want: bool = False):
        """Censored fit at a clipping level: linear parameters solved on the samples not at the level."""
        sign = 1.0 if side == "upper" else -1.0
        A = np.concatenate(self.base_columns(base_nl).rows)
        free = sign * self.y < sign * level - 3.0 * max(self.noise_sd, 1e-12)
        self.n_evaluations += 1
        if free.sum() < A.shape[1] + 1:
            return (math.inf, None, None) if want else math.inf
        theta, _ = self.solve(A[free], self.y[free])
        pred = A @ theta
        pred = np.minimum(pred, level) if side == "upper" else np.maximum(pred, level)
        r = self.y - pred
        return (float(r @ r), theta, r) if want else float(r @ r)

    def saturation(self) -> Candidate:
        """Censored fit of a clipping level, both sides; the better side stands for the cause."""
        out = None
        for side in ("upper", "lower"):
            sign = 1.0 if side == "upper" else -1.0
            ys = sign * self.y
            top, bottom = float(np.max(ys)), float(np.min(ys))
            levels = sign * (top - np.linspace(0.0, 0.3, 31) * (top - bottom))
            vals = [self.saturation_rss(side, L, self.base_nl) for L in levels]
            i = int(np.argmin(vals))
            a, b = sorted((levels[max(i - 1, 0)], levels[min(i + 1, len(levels) - 1)]))
            level = float(levels[i])
            if b > a:
                res = minimize_scalar(lambda L: self.saturation_rss(side, L, self.base_nl), bounds=(a, b),
                                      method="bounded", options={"xatol": 1e-3 * max(self.noise_sd, 1e-9)})
                if res.fun < vals[i]:
                    level = float(res.x)
            c = self._saturation_candidate(side, level, self.base_nl, "fixed base")
            if c is not None and (out is None or c.bic < out.bic):
                out = c
        return out

    def _saturation_candidate(self, side: str, level: float, base_nl: Mapping[str, float], stage: str):
        rss, theta, _ = self.saturation_rss(side, level, base_nl, want=True)
        if theta is None:
            return None
        model = self.extension(("saturation",), saturation_side=side)
        params = {**dict(base_nl), **dict(zip(self.base_lin, map(float, theta))), "saturation_level": float(level)}
        c = Candidate("saturation", f"clipped from {'above' if side == 'upper' else 'below'}", model, params,
                      model.n_params, rss, self.n, estimates_of("saturation", params, model),
                      hyperparameters={"saturation_side": side})
        c.stage = stage
        return self._finish(c)

    # --- stage 2: the base's nonlinear parameters free as well --------------------
    def joint(self, c: Candidate, max_nfev: int = 15) -> Candidate:
        """Refine a stage-1 candidate with the base's nonlinear parameters free too."""
        if not self.base_nl_names:
            return c
        if c.cause == "saturation":
            side = c.hyperparameters["saturation_side"]
            names = list(self.base_nl_names)
            lo = np.array([self.bounds_of(self.base, n)[0] for n in names])
            hi = np.array([self.bounds_of(self.base, n)[1] for n in names])
            level = c.params["saturation_level"]

            def fun(x):
                return self.saturation_rss(side, level, dict(zip(names, x)), want=True)[2]

            x0 = np.clip([c.params[n] for n in names], lo, hi)
            res = least_squares(fun, x0, bounds=(lo, hi), method="trf", diff_step=1e-4, x_scale=hi - lo,
                                max_nfev=max_nfev)
            out = self._saturation_candidate(side, level, dict(zip(names, res.x)), "joint")
            return out if out is not None and out.rss < c.rss else c
        model = c.model
        nl = list(model.nonlinear_names)
        free = [(n, _is_log(n)) for n in nl if n != "interference_frequency"]
        start = {n: c.params[n] for n in nl}
        z = self.refine(model, start, free, max_nfev=max_nfev)
        out = self.candidate(c.cause, c.label, model, z, c.hyperparameters, stage="joint")
        out.validation_rss, out.validation_explained = c.validation_rss, c.validation_explained
        return out if out.rss <= c.rss else c

    # --- validation (evidence only) ---------------------------------------------
    def validation_rss(self, model: HysteresisModel, params: Mapping[str, float]) -> float:
        """Sum of squares over the validation records, whole length."""
        total = 0.0
        for r in self.validation:
            pred = model.simulate(r.u, r.dt, params, input_range=self.input_range)
            d = r.y - pred
            total += float(d @ d)
        return total

    def score_validation(self, candidates: Sequence[Candidate]) -> None:
        if not self.validation:
            return
        if math.isnan(self.null.validation_rss):
            self.null.validation_rss = self.validation_rss(self.base, self.null.params)
            self.null.validation_explained = 0.0
        for c in candidates:
            c.validation_rss = self.validation_rss(c.model, c.params)
            c.validation_explained = 1.0 - c.validation_rss / self.null.validation_rss

    # --- composite (secondary causes) ---------------------------------------------
    def composite(self, primary: Candidate, other: Candidate, max_nfev: int = 10) -> Candidate | None:
        """The primary's extension plus another cause, refined from both fits (separable causes only)."""
        if "saturation" in (primary.cause, other.cause):
            return None
        hyper = {**primary.hyperparameters, **other.hyperparameters}
        model = self.extension((primary.cause, other.cause), **hyper)
        start = {n: primary.params.get(n, other.params.get(n)) for n in model.nonlinear_names}
        free = [(n, _is_log(n)) for n in model.nonlinear_names if n != "interference_frequency"]
        z = self.refine(model, start, free, max_nfev=max_nfev) if free else start
        c = self.candidate(other.cause, f"{primary.label} + {other.label}", model, z, hyper, stage="joint")
        c.estimates = estimates_of(other.cause, c.params, model)
        c.delta_bic = c.bic - primary.bic  # against the primary alone
        c.explained = 1.0 - c.rss / primary.rss
        c.limit = self.limit_of(other.cause, c.estimates)
        return c


def _local_minima(vals: np.ndarray, n: int) -> list[int]:
    """Indices of the n lowest local minima of a sampled curve (ends included)."""
    v = np.asarray(vals, dtype=float)
    if v.size < 3:
        return [int(np.argmin(v))]
    left = np.r_[True, v[1:] <= v[:-1]]
    right = np.r_[v[:-1] <= v[1:], True]
    idx = np.flatnonzero(left & right)
    return [int(i) for i in idx[np.argsort(v[idx])][:n]]


def prominence(amp: np.ndarray, half_width: int = 50) -> np.ndarray:
    """A spectrum over its running geometric mean (a peak stands out of its neighbourhood, whatever
    the slope)."""
    from scipy.ndimage import uniform_filter1d

    log_amp = np.log(np.maximum(amp, 1e-300))
    return np.exp(log_amp - uniform_filter1d(log_amp, size=2 * half_width + 1, mode="nearest"))


# --- library screen (pysindy) -------------------------------------------------------
def library_screen(screen: Screen, residuals: Sequence[RecordResidual], max_terms: int = 8,
                   n_taus: int = 10) -> dict:
    """Sparse regression (pysindy FROLS) of the null's residual on a library of candidate terms.

    Forward orthogonal least squares adds one term at a time, the one that
    explains most of what is left; the path is cut where BIC is lowest.
    Returns {"terms": [{name, group, explained, order}], "groups": {cause: share of the null's
    residual sum of squares explained}, "relaxation_taus": [time constants of kept low-pass terms]}.
    """
    import pysindy as ps

    T = screen.scale.time
    taus = np.exp(np.linspace(math.log(TAU_BOUNDS[0] * T * 5), math.log(TAU_BOUNDS[1] * T / 5), n_taus))
    creeps = np.exp(np.linspace(math.log(screen.creep_min), math.log(CREEP_TIME_BOUNDS[1] * T / 10), 5))
    null_theta = np.array([screen.null.params[n] for n in screen.base_lin])
    bc = screen.base_columns(screen.base_nl, full=True)
    # an interference candidate frequency: the pooled coherent spectrum's peak
    dt = max(p.record.dt for p in screen.parts)  # below every record's Nyquist frequency
    f, amp = coherent_spectrum(screen.null_residuals(), 1.0 / T, 0.45 / dt)
    peak = spectral_peaks(f, prominence(amp), n=1)
    names, groups, blocks = [], [], []
    y_hat_rows = np.concatenate([rows @ null_theta for rows in bc.rows])
    q_hi = np.quantile(y_hat_rows, [0.90, 0.97])
    q_lo = np.quantile(y_hat_rows, [0.03, 0.10])
    for m, p in enumerate(screen.parts):
        r = p.record
        n = r.t.size
        y_hat = np.column_stack([bc.full[m][c] for c in screen.base_lin]) @ null_theta
        dy = np.gradient(y_hat, r.dt)
        ddy = np.gradient(dy, r.dt)
        a, b0, b1 = (np.array(c) for c in zip(*(first_order_foh(float(t), r.dt) for t in taus)))
        lp = lowpass1_bank(np.ascontiguousarray(r.u), a, b0, b1)
        tt = np.arange(n) * r.dt
        cols = [lp[j] for j in range(len(taus))] + [dy, ddy] + [-np.expm1(-tt / c) for c in creeps]
        if peak:
            cols += [np.sin(2 * np.pi * peak[0][0] * tt), np.cos(2 * np.pi * peak[0][0] * tt)]
        cols += [np.maximum(y_hat - L, 0.0) for L in q_hi] + [np.maximum(L - y_hat, 0.0) for L in q_lo]
        blocks.append(np.stack([c[p.rows] for c in cols], axis=1))
    names = ([f"L_{t:.3g}s[u]" for t in taus] + ["d/dt y_model", "d2/dt2 y_model"]
             + [f"1-exp(-t/{c:.3g}s)" for c in creeps]
             + ([f"sin {peak[0][0]:.4g}Hz", f"cos {peak[0][0]:.4g}Hz"] if peak else [])
             + [f"max(y_model-{L:.3g},0)" for L in q_hi] + [f"max({L:.3g}-y_model,0)" for L in q_lo])
    tau_of = [float(t) for t in taus] + [None] * (len(names) - len(taus))
    groups = (["relaxation"] * len(taus) + ["delay", "resonance"] + ["creep"] * len(creeps)
              + (["interference"] * 2 if peak else []) + ["saturation"] * 4)
    Theta = np.concatenate(blocks)
    # orthogonal to the base model's regressors, unit norm
    A = np.concatenate(bc.rows)
    d = np.sqrt(np.einsum("ij,ij->j", A, A))
    d[~(d > 0)] = 1.0
    coef = np.linalg.lstsq(A / d, Theta, rcond=1e-10)[0]
    Theta = Theta - (A / d) @ coef
    norms = np.sqrt(np.einsum("ij,ij->j", Theta, Theta))
    keep = norms > 1e-9 * max(float(norms.max()), 1e-300)
    Theta = Theta[:, keep] / norms[keep]
    names = [n for n, k in zip(names, keep) if k]
    groups = [g for g, k in zip(groups, keep) if k]
    tau_of = [t for t, k in zip(tau_of, keep) if k]
    target = screen.null_residual
    opt = ps.FROLS(max_iter=min(max_terms, Theta.shape[1]), alpha=1e-10, normalize_columns=False, unbias=True)
    opt.fit(Theta, target)
    # choose the number of terms by BIC along FROLS's forward path
    n = target.size
    path = [np.asarray(h, dtype=float).reshape(-1) for h in opt.history_]
    rss_path = [float(np.sum((target - Theta @ h) ** 2)) for h in path]
    bics = [n * math.log(max(r, 1e-300) / n) + np.count_nonzero(h) * math.log(n) for r, h in zip(rss_path, path)]
    best = int(np.argmin(bics))
    total = rss_path[0] if rss_path else float(target @ target)
    terms, explained_by = [], {g: 0.0 for g in dict.fromkeys(groups)}
    for k in range(1, best + 1):
        new = [j for j in np.flatnonzero(path[k]) if path[k - 1][j] == 0.0]
        share = (rss_path[k - 1] - rss_path[k]) / total if total > 0 else 0.0
        for j in new:
            terms.append({"name": names[j], "group": groups[j], "explained": share / len(new), "order": k})
            explained_by[groups[j]] += share / len(new)
    kept = np.flatnonzero(path[best]) if path else []
    kept_taus = [tau_of[j] for j in kept if tau_of[j] is not None]
    return {"method": "pysindy FROLS (forward orthogonal least squares), number of terms by BIC",
            "terms": terms, "groups": explained_by,
            "explained_total": float(1.0 - rss_path[best] / total) if total > 0 else 0.0,
            "relaxation_taus": kept_taus, "n_library": len(names), "n_terms": int(best)}


def run_screen(screen: Screen, residuals: Sequence[RecordResidual], max_relaxation: int = MAX_RELAXATION,
               bic_threshold: float = BIC_THRESHOLD, joint_nfev: int = 10, joint_share: float = 0.05,
               max_joint: int = 3,
               progress: Callable[[str], None] | None = None) -> dict:
    """Every candidate on the screen; returns {"library", "candidates" (best per cause), "relaxation_variants"}."""
    say = progress or (lambda s: None)
    say("library screen (pysindy FROLS)")
    library = library_screen(screen, residuals)
    say("relaxation")
    variants = screen.relaxation(max_relaxation, seeds=library["relaxation_taus"])
    best_relax = min(variants, key=lambda c: c.bic)
    say("delay")
    cands = [best_relax, screen.delay()]
    say("resonance")
    cands.append(screen.resonance())
    say("creep")
    cands.append(screen.creep())
    say("interference")
    cands.append(screen.interference())
    say("saturation")
    cands.append(screen.saturation())
    # stage 2: what could be named is refined with the base's nonlinear parameters free: the best
    # candidate and those at least ``joint_share`` as strong (at most ``max_joint``)
    best = min(c.delta_bic for c in cands)
    plausible = sorted([c for c in cands if c.delta_bic < -bic_threshold and c.delta_bic <= joint_share * best],
                       key=lambda c: c.bic)[:max_joint]
    for c in plausible:
        i = cands.index(c)
        if c.cause == "relaxation":
            say("relaxation (joint)")
            variants = [screen.joint(v, max_nfev=joint_nfev) for v in variants]
            cands[i] = min(variants, key=lambda c: c.bic)
        else:
            say(f"{c.cause} (joint)")
            cands[i] = screen.joint(c, max_nfev=joint_nfev)
    best_relax = cands[0]
    screen.score_validation(cands + [v for v in variants if v is not best_relax])
    return {"library": library, "candidates": cands, "relaxation_variants": variants}


def decide(null: Candidate, candidates: Sequence[Candidate], bic_threshold: float = BIC_THRESHOLD,
           min_explained: float = MIN_EXPLAINED) -> Candidate | None:
    """The named cause: the lowest BIC, if it beats the null by ``bic_threshold``, explains at
    least ``min_explained`` of the null's sum of squares and is within the cause's meaning (see
    ``Screen.limit_of``); else None (cause 'none')."""
    ok = [c for c in candidates if c.delta_bic < -bic_threshold and c.explained >= min_explained and not c.limit]
    return min(ok, key=lambda c: c.bic) if ok else None
