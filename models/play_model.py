"""The Prandtl-Ishlinskii family: a polynomial of the input, an optional q*u''
term, an optional output offset, and a weighted sum of one-sided play
operators with optional dynamic envelopes. ``classical-pi`` and ``mrpim`` are
configurations of this one structure.

    y(k) = sum_{j=1..K} p_j u(k)^j + q u''(k) + sum_{i=1..N} a_i W_i(k) + c

Thresholds r_i = (i-1)/N * ||u||_inf (eq. 8), with ||u||_inf taken over
``input_range`` (identifiers pass the identification records' range).
Play state starts at W_i(0) = max(h_l(0) - r_i, min(h_r(0), 0)): eq. 3 with
its zero initial state; we read eq. 6's y(0) as that same zero (an actuator
at rest before the record starts).
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from .base import DataScale, HysteresisModel, Parameter
from .derivatives import DERIVATIVE_METHODS, backward_second_difference_at, derivatives
from .errors import ModelError
from .hyperparameters import MAX_OPERATORS, check_bool, check_choice, check_int, check_number
from .inverse import (RecursionRows, StepStructure, distinct_operating_points, reachable_operating_points,
                      recursion_activity)
from .pi_stepper import SteppableStructure
from .kernels import (
    pi_output,
    pi_output_batch,
    pi_output_window,
    pi_output_window_batch,
    play_operators,
    play_operators_window,
    play_operators_window_batch,
)

# Default bounds, in units of the data scale (see DataScale).
POLY_BOUND = 20.0  # |p_j| <= POLY_BOUND * y / u**j (5 would exclude Table 2: p2 = 5.58 vs 5.16)
WEIGHT_BOUND = 20.0  # |a_i| <= WEIGHT_BOUND * y / u
Q_BOUND = 1.0  # |q| <= Q_BOUND * y * time**2 / u
ENVELOPE_BOUND = 0.1  # |gamma|, |lambda| <= ENVELOPE_BOUND * time  (seconds)
_NO_ROWS = np.empty(0, dtype=np.int64)  # the play kernels' "a contiguous window"


class PlayOperatorModel(SteppableStructure, HysteresisModel):
    """Shared implementation; use ``ClassicalPI`` or ``MRPIM``."""

    def __init__(
        self,
        n_operators: int = 13,
        poly_order: int = 4,
        q_term: bool = True,
        envelopes: bool = True,
        offset: bool = True,
        derivative: str = "backward",
        derivative_window: float = 0.05,
    ):
        name = self.name
        self.n_operators = check_int(name, "n_operators", n_operators, 1, MAX_OPERATORS)
        self.poly_order = check_int(name, "poly_order", poly_order, 0, 12)
        self.q_term = check_bool(name, "q_term", q_term)
        self.envelopes = check_bool(name, "envelopes", envelopes)
        self.offset = check_bool(name, "offset", offset)
        self.derivative = check_choice(name, "derivative", derivative, DERIVATIVE_METHODS)
        self.derivative_window = check_number(name, "derivative_window", derivative_window, positive=True)

    # --- parameters ------------------------------------------------------
    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        u, y, T = scale.u, scale.y, scale.time
        params = []
        if self.envelopes:
            b = ENVELOPE_BOUND * T
            params.append(Parameter("gamma", 0.0, -b, b, False, "left envelope: h_l = u - gamma |u'| (s)", unit="s"))
            params.append(Parameter("lambda", 0.0, -b, b, False, "right envelope: h_r = u + lambda |u'| (s)", unit="s"))
        for j in range(1, self.poly_order + 1):
            b = POLY_BOUND * y / u**j
            params.append(Parameter(f"p{j}", 0.0, -b, b, True, f"polynomial coefficient of u^{j}", unit=f"y/u^{j}"))
        if self.q_term:
            b = Q_BOUND * y * T * T / u
            params.append(Parameter("q", 0.0, -b, b, True, "weight of the input's second derivative", unit="y*s^2/u"))
        for i in range(1, self.n_operators + 1):
            b = WEIGHT_BOUND * y / u
            params.append(Parameter(f"a{i}", 0.0, -b, b, True, f"weight of play operator {i}", unit="y/u"))
        if self.offset:
            params.append(self.offset_parameter(scale))
        return params

    # --- structure -------------------------------------------------------
    def thresholds(self, u: np.ndarray, input_range=None) -> np.ndarray:
        """r_i = (i-1)/N * ||u||_inf over ``input_range`` (eq. 8)."""
        lo, hi = self._input_range(u, input_range)
        norm = max(abs(lo), abs(hi))
        return np.arange(self.n_operators, dtype=float) / self.n_operators * norm

    def _signals(self, u: np.ndarray, dt: float):
        du, ddu = derivatives(u, dt, self.derivative, self.derivative_window)
        return np.abs(du), ddu

    def _column_indices(self) -> dict[str, list[int]]:
        cached = self.__dict__.get("_column_index_cache")
        if cached is None:
            index = {n: i for i, n in enumerate(self.param_names)}
            cached = self.__dict__["_column_index_cache"] = {
                "weights": [index[f"a{i}"] for i in range(1, self.n_operators + 1)],
                "poly": [index[f"p{j}"] for j in range(1, self.poly_order + 1)],
            }
        return cached

    # --- evaluation ------------------------------------------------------
    def _parameter_arrays(self, P: np.ndarray) -> tuple:
        """(gammas, lams, weights, polys, qs, offsets) of the parameter sets P (n_set, n_params).
        A single set's arrays are kept and reused while the same set comes back (a fitted model,
        a benchmark, a stepper's replay simulate one set again and again)."""
        single = P.shape[0] == 1
        key = P.tobytes() if single else None
        cached = self.__dict__.get("_parameter_arrays_cache")
        if single and cached is not None and cached[0] == key:
            return cached[1]
        n_set = P.shape[0]
        idx = self._column_indices()
        names = self.param_names
        zeros = np.zeros(n_set)
        arrays = (P[:, names.index("gamma")].copy() if self.envelopes else zeros,
                  P[:, names.index("lambda")].copy() if self.envelopes else zeros,
                  np.ascontiguousarray(P[:, idx["weights"]]), np.ascontiguousarray(P[:, idx["poly"]]),
                  P[:, names.index("q")].copy() if self.q_term else zeros,
                  P[:, names.index("offset")].copy() if self.offset else zeros)
        if single:
            self.__dict__["_parameter_arrays_cache"] = (key, arrays)
        return arrays

    def _record_thresholds(self, u: np.ndarray, input_range) -> np.ndarray:
        """``thresholds`` for a simulation: kept per ``input_range`` (it does not depend on u then)."""
        if input_range is None:
            return self.thresholds(u, None)
        key = self._input_range(u, input_range)
        cached = self.__dict__.get("_threshold_cache")
        if cached is None or cached[0] != key:
            cached = self.__dict__["_threshold_cache"] = (key, self.thresholds(u, key))
        return cached[1]

    def _batch_arguments(self, u, dt: float, param_sets, input_range):
        u = self._check_input(u, dt)
        P = self._check_param_sets(param_sets)
        r = self._record_thresholds(u, input_range)
        backward = self.derivative == "backward"
        if backward:
            abs_du = ddu = u[:0]
        else:
            abs_du, ddu = self._signals(u, dt)
        gammas, lams, weights, polys, qs, offsets = self._parameter_arrays(P)
        return u, backward, abs_du, ddu, gammas, lams, r, weights, polys, qs, offsets

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        u, backward, abs_du, ddu, gammas, lams, r, weights, polys, qs, offsets = self._batch_arguments(
            u, dt, param_sets, input_range)
        if gammas.shape[0] == 1:
            y = pi_output(u, dt, backward, abs_du, ddu, gammas[0], lams[0], r, weights[0], polys[0], qs[0],
                          offsets[0], 0.0)
            return y[None, :]
        return pi_output_batch(u, dt, backward, abs_du, ddu, gammas, lams, r, weights, polys, qs, offsets, 0.0)

    def simulate_window_batch(self, u, dt: float, param_sets, window, input_range=None) -> np.ndarray:
        u, backward, abs_du, ddu, gammas, lams, r, weights, polys, qs, offsets = self._batch_arguments(
            u, dt, param_sets, input_range)
        start, stop = self._window_bounds(u, window)
        if gammas.shape[0] == 1:  # the serial kernel: no parallel-region overhead
            Y = pi_output_window(u, dt, backward, abs_du, ddu, gammas[0], lams[0], r, weights[0], polys[0], qs[0],
                                 offsets[0], 0.0, start, stop)[None, :]
        else:
            Y = pi_output_window_batch(u, dt, backward, abs_du, ddu, gammas, lams, r, weights, polys, qs, offsets,
                                       0.0, start, stop)
        rows = self._window_rows(u, window)
        return Y if rows is None else np.ascontiguousarray(Y[:, rows - start])

    def play_outputs(self, u, dt: float, gamma: float = 0.0, lam: float = 0.0, input_range=None) -> np.ndarray:
        """Outputs of the N (rate-dependent) play operators, shape (T, N)."""
        u = self._check_input(u, dt)
        abs_du, _ = self._signals(u, dt)
        if not self.envelopes:
            gamma = lam = 0.0
        return play_operators(u - gamma * abs_du, u + lam * abs_du, self.thresholds(u, input_range), 0.0)

    def regressors(self, u, dt: float, nonlinear: Mapping[str, float] | None = None, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        nonlinear = dict(nonlinear or {})
        expected = set(self.nonlinear_names)
        if set(nonlinear) != expected:
            raise ModelError(
                f"{self.name}: regressors need exactly the nonlinear parameters "
                f"{sorted(expected)}, got {sorted(nonlinear)}"
            )
        gamma = nonlinear.get("gamma", 0.0)
        lam = nonlinear.get("lambda", 0.0)
        _, ddu = self._signals(u, dt)
        F = self.play_outputs(u, dt, gamma, lam, input_range)
        cols = {f"p{j}": u**j for j in range(1, self.poly_order + 1)}
        if self.q_term:
            cols["q"] = ddu
        for i in range(self.n_operators):
            cols[f"a{i + 1}"] = F[:, i]
        if self.offset:
            cols["offset"] = np.ones_like(u)
        return np.stack([cols[n] for n in self.linear_names], axis=1)

    # --- the step structure (the causal inverse, models/inverse.py) -----
    def step_structure(self, dt: float, params: Mapping[str, float], input_range, n_samples: int) -> StepStructure:
        r = self.thresholds(np.zeros(1), input_range)
        return StepStructure(
            r_lo=r, r_hi=np.zeros_like(r),
            g_lo=params["gamma"] if self.envelopes else 0.0, g_hi=params["lambda"] if self.envelopes else 0.0,
            weights=np.array([params[f"a{i}"] for i in range(1, self.n_operators + 1)]),
            poly=np.array([params[f"p{j}"] for j in range(1, self.poly_order + 1)]),
            q=params["q"] if self.q_term else 0.0,
            base=np.full(n_samples, params["offset"] if self.offset else 0.0))

    #: operating points of ``inverse_recursion_rows``: the input range is cut into this many bands
    RECURSION_LEVELS = 32

    def inverse_recursion_rows(self, u, dt: float, nonlinear: Mapping[str, float], window=None,
                               input_range=None, n_levels: int | None = None) -> RecursionRows:
        """The exact inverse's recursion coefficients (``inverse.recursion_radius``) at the distinct
        operating points of the forward run on u within ``window`` (default: the whole record; points
        from its third sample on), as rows linear in the linear parameters. With the plays' edges and
        sign(u') fixed (``recursion_activity``), per play on its lower edge c0 gets a_i (1 - gamma s/dt)
        and c1 a_i gamma s/dt, on its upper edge c0 gets a_i (1 + lambda s/dt) and c1 -a_i lambda s/dt;
        the polynomial adds p'(u) to c0; q adds (1, -2, 1) / dt^2 to (c0, c1, c2). Thinned by
        ``distinct_operating_points`` (``n_levels`` bands of the input range)."""
        u = self._check_input(u, dt)
        g_lo, g_hi = self._recursion_rates(nonlinear)
        input_range = self._input_range(u, input_range)
        r = self.thresholds(u, input_range)
        start, stop = (0, u.size) if window is None else self._window_bounds(u, window)
        first = max(start, 2)  # the recursion starts at the third sample (``recursion_radius``)
        edge, sign = recursion_activity(u, float(dt), r, np.zeros_like(r), g_lo, g_hi, first, max(first, stop))
        samples = np.arange(first, max(first, stop))
        rows = None if window is None else self._window_rows(u, window)
        if rows is not None:
            pick = np.isin(samples, rows)
            samples, edge, sign = samples[pick], edge[pick], sign[pick]
        levels = self.RECURSION_LEVELS if n_levels is None else check_int(self.name, "n_levels", n_levels, 1)
        keep = distinct_operating_points(edge, sign, u[samples], input_range, levels)
        return self._recursion_rows(edge[keep], sign[keep], u[samples[keep]], samples[keep], dt, g_lo, g_hi)

    def inverse_recursion_cover(self, dt: float, nonlinear: Mapping[str, float], input_range,
                                n_levels: int | None = None) -> RecursionRows:
        """The rows of ``inverse_recursion_rows`` at every operating point an input within
        ``input_range`` can reach (``inverse.reachable_operating_points``: plays 1..k on the lower edge
        or 1..j on the upper edge, each sign(u'), u at the ends of ``n_levels`` bands of the range and
        of each pattern's interval), rows that coincide merged; ``sample`` is -1 (no record)."""
        g_lo, g_hi = self._recursion_rates(nonlinear)
        lo, hi = map(float, input_range)
        levels = self.RECURSION_LEVELS if n_levels is None else check_int(self.name, "n_levels", n_levels, 1)
        r = self.thresholds(np.array([lo, hi]), (lo, hi))
        edge, sign, uk = reachable_operating_points(r, (lo, hi), levels, g_lo, g_hi)
        rows = self._recursion_rows(edge, sign, uk, np.full(uk.size, -1), dt, g_lo, g_hi)
        _, keep = np.unique(np.hstack([rows.c0, rows.c1, rows.c2]), axis=0, return_index=True)
        keep = np.sort(keep)
        return RecursionRows(rows.c0[keep], rows.c1[keep], rows.c2[keep], rows.sample[keep], rows.u[keep],
                             rows.sign[keep], rows.edge[keep], rows.dt)

    def _recursion_rates(self, nonlinear) -> tuple[float, float]:
        """(gamma, lambda) of the nonlinear parameters the recursion rows are taken at."""
        if self.derivative != "backward":
            raise ModelError(f"{self.name}: the inverse recursion needs derivative='backward'")
        nonlinear = dict(nonlinear or {})
        if set(nonlinear) != set(self.nonlinear_names):
            raise ModelError(f"{self.name}: recursion rows need exactly the nonlinear parameters "
                             f"{sorted(self.nonlinear_names)}, got {sorted(nonlinear)}")
        return float(nonlinear.get("gamma", 0.0)), float(nonlinear.get("lambda", 0.0))

    def _recursion_rows(self, edge, sign, uk, samples, dt, g_lo, g_hi) -> RecursionRows:
        """The recursion's coefficients at operating points (edge, sign, u) as rows linear in the
        linear parameters (``inverse_recursion_rows``)."""
        names = self.linear_names
        n = len(uk)
        c0, c1, c2 = (np.zeros((n, len(names))) for _ in range(3))
        inv_dt = 1.0 / float(dt)
        lower = edge == 1
        upper = edge == -1
        first_weight = names.index("a1") if self.n_operators else 0
        ops = slice(first_weight, first_weight + self.n_operators)
        s = sign[:, None]
        c0[:, ops] = np.where(lower, 1.0 - g_lo * s * inv_dt, 0.0) + np.where(upper, 1.0 + g_hi * s * inv_dt, 0.0)
        c1[:, ops] = np.where(lower, g_lo * s * inv_dt, 0.0) - np.where(upper, g_hi * s * inv_dt, 0.0)
        for j in range(1, self.poly_order + 1):
            c0[:, names.index(f"p{j}")] = j * uk ** (j - 1)
        if self.q_term:
            iq = names.index("q")
            c0[:, iq] = inv_dt * inv_dt
            c1[:, iq] = -2.0 * inv_dt * inv_dt
            c2[:, iq] = inv_dt * inv_dt
        return RecursionRows(c0, c1, c2, samples, uk, sign, edge, float(dt))

    # --- windowed regressors (what identifiers fit) -----------------------
    def _static_columns(self, u: np.ndarray, dt: float, start: int, stop: int,
                        rows: np.ndarray | None = None) -> dict[str, np.ndarray]:
        """Columns that do not depend on gamma, lambda, on rows [start, stop) (or at ``rows`` within it)."""
        pick = slice(None) if rows is None else rows - start
        uw = u[start:stop][pick]
        cols = {f"p{j}": uw**j for j in range(1, self.poly_order + 1)}
        if self.q_term:
            if self.derivative == "backward" and rows is not None:
                cols["q"] = backward_second_difference_at(u, dt, rows)
            elif self.derivative == "backward":  # needs only two samples before the window
                s0 = max(0, start - 2)
                _, ddu = derivatives(u[s0:stop], dt, "backward")
                cols["q"] = ddu[start - s0:][pick]
            else:
                cols["q"] = self._signals(u, dt)[1][start:stop][pick]
        if self.offset:
            cols["offset"] = np.ones(uw.size)
        return cols

    def windowed_regressors_batch(self, u, dt: float, nonlinear_sets, window, input_range=None) -> np.ndarray:
        """(n_sets, n_rows, n_linear); each set's matrix is column-major (a transposed view)."""
        u = self._check_input(u, dt)
        sets = np.asarray(nonlinear_sets, dtype=float)
        sets = sets.reshape(1, -1) if sets.ndim < 2 else sets
        if sets.shape[1] != len(self.nonlinear_names):
            raise ModelError(
                f"{self.name}: regressors need the nonlinear parameters {list(self.nonlinear_names)}, "
                f"got sets of shape {sets.shape}"
            )
        start, stop = self._window_bounds(u, window)
        rows = self._window_rows(u, window)
        n_rows = stop - start if rows is None else rows.size
        n_set = sets.shape[0]
        if self.envelopes:
            gammas = np.ascontiguousarray(sets[:, self.nonlinear_names.index("gamma")])
            lams = np.ascontiguousarray(sets[:, self.nonlinear_names.index("lambda")])
        else:
            gammas = lams = np.zeros(n_set)
        backward = self.derivative == "backward"
        abs_du = u[:0] if backward else self._signals(u, dt)[0]
        r = self.thresholds(u, input_range)
        names = self.linear_names
        out = np.empty((n_set, len(names), n_rows))  # columns contiguous
        first = names.index("a1")  # a1..aN are consecutive
        ops = out[:, first:first + self.n_operators, :]
        picked = _NO_ROWS if rows is None else rows
        if n_set == 1:
            play_operators_window(u, dt, backward, abs_du, gammas[0], lams[0], r, 0.0, start, picked, ops[0])
        else:
            play_operators_window_batch(u, dt, backward, abs_du, gammas, lams, r, 0.0, start, picked, ops)
        for name, col in self._static_columns(u, dt, start, stop, rows).items():
            out[:, names.index(name), :] = col
        return out.transpose(0, 2, 1)

    def windowed_regressors(self, u, dt: float, nonlinear: Mapping[str, float] | None, window,
                            input_range=None) -> np.ndarray:
        nonlinear = dict(nonlinear or {})
        if set(nonlinear) != set(self.nonlinear_names):
            raise ModelError(
                f"{self.name}: regressors need exactly the nonlinear parameters "
                f"{sorted(self.nonlinear_names)}, got {sorted(nonlinear)}"
            )
        sets = np.array([[float(nonlinear[n]) for n in self.nonlinear_names]])
        return self.windowed_regressors_batch(u, dt, sets, window, input_range)[0]
