"""``varpro``: separable least squares (variable projection, Golub & Pereyra 1973).

Many hysteresis models are linear in most of their parameters once a few
nonlinear ones are fixed (MRPIM: everything but gamma and lambda). For given
nonlinear parameters theta_N the model's ``windowed_regressors`` give, per fit
record m, the matrix Phi_m (scored rows) with y = Phi_m @ theta_L. With row
weights sqrt(k_m / n_m) the stacked least-squares problem

    min_{theta_L} || A(theta_N) theta_L - b ||^2,   A = [w_m Phi_m],  b = [w_m y_m]

is eq. 9 exactly, and is solved exactly:

* columns are scaled to unit norm (D); the solve works on A_s = A D^-1;
* the condition number of A_s is computed (eigenvalues of A_s^T A_s in the
  search, singular values of A_s for the reported optimum);
* if it exceeds ``max_condition`` (default 1e6) the solve is regularised by a
  ridge on the scaled coefficients, alpha = s_max / max_condition, which damps
  only the directions with singular values below s_max / max_condition; the
  Fit says so and names the parameters of those directions;
* linear parameters keep their bounds: when the unconstrained solution leaves
  them, the bounded problem is solved with scipy.optimize.lsq_linear (on the
  equivalent small system, same ridge), e.g. Preisach's non-negative weights.
* ``stable_inverse`` (default off; the unconstrained solve above is then unchanged): every linear
  solve keeps the model's exact inverse stable (models/inverse.py, "Why the exact inverse
  diverges"). With the nonlinear parameters fixed, the inverse's error recursion
  c0 e(k) + c1 e(k-1) + c2 e(k-2) = 0 has coefficients linear in the linear parameters at each
  operating point (which plays are on which edge, sign(u'), u: ``inverse_recursion_rows``, taken
  at the distinct operating points of the fit records, and ``inverse_recursion_cover``: every
  operating point any input within the input range can reach). Both roots have modulus <= rho exactly
  when the four Schur-Cohn conditions ``STABILITY_CONDITIONS`` hold: linear inequalities G x >= 0.
  Where the unconstrained solution (or a bound) breaks one, the same ridge-regularised objective
  is minimised under them and the bounds (``linear.spectral_inequality_solve``: an LDP solved by
  NNLS). rho is ``inverse_radius``, by default exp(-dt / T), T the fit records' shortest drive
  period: an input error decays by e within it. P(1) = c0 + c1 + c2 is the rate-free slope, so
  the conditions include a loading curve that increases after a reversal. The Fit's diagnostics
  (``stable_inverse``) and notes name the constrained points, the active rows and the largest root
  at them.

The nonlinear parameters are searched with several starts: the start point
(the model's defaults or ``start``) and ``n_candidates`` points of a scrambled
Halton sequence in their bounds (seeded) are evaluated as one batch; local
searches (scipy.optimize.least_squares, trust-region reflective, bounded,
Jacobian by forward differences evaluated as one batch) run from the
``n_starts`` best; a later search that comes within ``merge_radius`` (2 % of
each bound's width) of an earlier search's optimum stops there, since it
would end in the same place; the best result wins. A model with no
nonlinear parameter is a single linear solve. Parameters a model declares
``log_scale`` (positive, spanning decades: relaxation times, a mode's
frequency) are searched in log coordinates: candidates, steps, the trust
region and the merge radius all see log z.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from scipy.optimize import least_squares, lsq_linear
from scipy.stats import qmc

from .base import Identifier
from .errors import IdentificationError
from .jacobian import CachedResidual, forward_difference
from .linear import (UNDETERMINED_TOL, column_norms, dependent_columns, solve_spectrum, spectral_inequality_solve,
                     spectrum_from_gram, spectrum_from_qr, undetermined_count)
from .problem import MAX_BATCH_ELEMENTS, Problem

# a column whose spread on the scored rows is below this fraction of its largest magnitude is nearly constant:
# a weight fitted to that spread acts from rest (where the column is 0) on a level more than 20 times the
# largest change it was fitted on, an extrapolation the data cannot check. The fraction lies in the gap between
# the columns a drive excites and those it does not: on the virtual DEA's varpro fits of every matrix model
# with an intercept, the former vary by at least 12 % of their level (plays that turn, polynomial and state
# terms), the latter by at most 1.1 % (plays whose threshold lies above the input's span, moved only by the rate
# envelopes); any fraction in between sorts them alike (docs/identification.md)
NEAR_CONSTANT = 0.05
# fixing an undetermined direction may cost at most this relative increase of the fitness (rounding, the
# ridge); a bounded solve whose bounds pin the direction down costs more, and is kept whole
FREE_FIX = 1e-6
# a constraint row whose slack is below this fraction of |row| . |x| is active at the solution
ACTIVE_SLACK = 1e-9
# the four Schur-Cohn (Jury) conditions of c0 z^2 + c1 z + c2 with both roots of modulus <= rho, in the
# order of ``InverseConstraints`` rows; c0 > 0 follows from the first two (with any c2)
STABILITY_CONDITIONS = ("rho^2 c0 >= c2", "rho^2 c0 >= -c2", "rho^2 c0 + c2 >= rho c1", "rho^2 c0 + c2 >= -rho c1")


class Varpro(Identifier):
    """Separable least squares; see the module docstring."""

    name = "varpro"

    def __init__(self, n_starts: int = 2, n_candidates: int = 12, max_nfev: int = 40, max_condition: float = 1e6,
                 tol: float = 1e-6, fd_step: float = 1e-6, merge_radius: float = 0.02, stable_inverse: bool = False,
                 inverse_radius: float | None = None):
        self.n_starts = n_starts  # local searches, from the best candidates
        self.n_candidates = n_candidates  # Halton points evaluated before the local searches
        self.max_nfev = max_nfev  # residual evaluations per local search
        self.max_condition = max_condition  # ridge above this condition number of the scaled design
        self.tol = tol  # ftol = xtol = gtol of least_squares
        self.fd_step = fd_step  # forward-difference step, relative to each bound's width
        self.merge_radius = merge_radius  # a search this close (fraction of each width) to an earlier optimum stops
        self.stable_inverse = stable_inverse  # linear solves constrained to a stable exact inverse (module docstring)
        self.inverse_radius = inverse_radius  # largest root modulus allowed (None: exp(-dt / shortest drive period))

    def check(self, model, problem=None) -> None:
        if not model.has_linear_part:
            raise IdentificationError(
                f"method 'varpro' cannot identify model {model.name!r}: it has no linear parameters to solve "
                "exactly (use 'lsq' or 'mpso')")
        if self.stable_inverse:
            check_stable_inverse(model, self.inverse_radius)

    def search(self, problem, seed, start, x0=None) -> dict:
        return run(problem, seed, start, **self.get_params())


OPTIONS = Varpro().get_params()


#: what the cover rows of ``inverse_constraints`` are (``inverse_recursion_cover``)
RANGE_COVER = "every operating point an input reaches within the input range"


def check_stable_inverse(model, inverse_radius) -> None:
    """Refuse, in one line, a model or radius the stable-inverse constraint cannot work with."""
    if not hasattr(model, "inverse_recursion_cover"):
        raise IdentificationError(
            f"option stable_inverse: model {model.name!r} does not state its exact inverse's error recursion as "
            "linear rows (classical-pi and mrpim do)")
    if getattr(model, "derivative", "backward") != "backward":
        raise IdentificationError(f"option stable_inverse: model {model.name!r} has derivative="
                                  f"{model.derivative!r}; its exact inverse needs derivative='backward'")
    if inverse_radius is not None and (isinstance(inverse_radius, bool) or not (
            isinstance(inverse_radius, (int, float)) and 0.0 < inverse_radius <= 1.0)):
        raise IdentificationError(f"option inverse_radius must be in (0, 1] (or unset), got {inverse_radius!r}")


@dataclass
class InverseConstraints:
    """G x >= h on the linear parameters (``linear_names`` order, divided by the output scale): the
    Schur-Cohn conditions (``STABILITY_CONDITIONS``) at each operating point of ``rows``, rows
    ordered condition-major (all points of the first condition, then the second, ...)."""

    G: np.ndarray
    h: np.ndarray
    rows: object  # the stacked ``RecursionRows``
    record: np.ndarray  # per operating point, the fit record it comes from (len(records): the input range's cover)
    radius: np.ndarray  # per operating point, the largest root modulus allowed

    def describe(self, index: int, files: list[str], weight_names: list[str]) -> dict:
        """A constraint row as the operating point and condition it states."""
        n = self.rows.sample.size
        point, condition = index % n, index // n
        edge = self.rows.edge[point]
        return {"condition": STABILITY_CONDITIONS[condition],
                "record": files[self.record[point]] if self.record[point] < len(files) else RANGE_COVER,
                "sample": int(self.rows.sample[point]), "u": float(self.rows.u[point]),
                "direction": {1.0: "rising", -1.0: "falling"}.get(float(self.rows.sign[point]), "still"),
                "lower_edge": [weight_names[i] for i in np.flatnonzero(edge == 1)],
                "upper_edge": [weight_names[i] for i in np.flatnonzero(edge == -1)]}


class _SameBasin(Exception):
    """A local search reached the neighbourhood of an earlier search's optimum."""


@dataclass
class LinearSolution:
    """The exact solve of the linear parameters for one nonlinear parameter set."""

    linear: np.ndarray  # linear parameters in ``model.linear_names`` order
    fitness: float  # eq. 9
    residuals: np.ndarray  # weighted, stacked over records, divided by the problem's output_scale (order one)
    condition_number: float  # of the column-scaled weighted design matrix
    regularised: bool
    ridge: float  # alpha / s_max (0 when not regularised)
    bounded: bool  # the bounded solve was needed
    weak_directions: list  # [(singular value / s_max, {name: loading})] below 1 / max_condition
    n_undetermined: int = 0  # directions with singular value below UNDETERMINED_TOL * s_max (accurate solve only)
    fixed: dict = field(default_factory=dict)  # {name: value} linear parameters fixed because the data do not determine them
    condition_number_full: float = math.nan  # of the design before rank-deficient columns were fixed
    nearly_constant: list = field(default_factory=list)  # of ``fixed``: columns nearly constant on the scored rows
    inverse_constrained: bool = False  # the stable-inverse constraint moved the solution (some row active)
    active_constraints: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))  # active rows of G
    constraint_violation: float = 0.0  # largest relative violation of a constraint row at the solution


class SeparableProblem:
    """Linear solves and projected residuals of a ``Problem`` (public: the
    posterior and the ablation use it)."""

    def __init__(self, problem: Problem, max_condition: float = OPTIONS["max_condition"],
                 stable_inverse: bool = False, inverse_radius: float | None = None):
        model = problem.model
        if not model.has_linear_part:
            raise IdentificationError(
                f"method 'varpro' cannot identify model {model.name!r}: it has no linear parameters to solve "
                "exactly (use 'lsq' or 'mpso')"
            )
        self.problem = problem
        self.model = model
        self.max_condition = float(max_condition)
        names = model.param_names
        self.linear_names = model.linear_names
        self.nonlinear_names = model.nonlinear_names
        self.lin_idx = np.array([names.index(n) for n in self.linear_names], dtype=int)
        self.nl_idx = np.array([names.index(n) for n in self.nonlinear_names], dtype=int)
        # solved at order one: outputs, linear parameters and their bounds divided by the power of two
        # problem.output_scale (1 at ordinary scales); linear parameters and fitness are returned unscaled
        self.output_scale = problem.output_scale
        self.lin_lower = problem.lower[self.lin_idx] / self.output_scale
        self.lin_upper = problem.upper[self.lin_idx] / self.output_scale
        self.nl_lower = problem.lower[self.nl_idx]
        self.nl_upper = problem.upper[self.nl_idx]
        w = problem.row_weights
        self._ys = [np.ascontiguousarray(r.y[r.scored]) / self.output_scale for r in problem.records]
        self.b = np.concatenate([wm * y for wm, y in zip(w, self._ys)])
        # the linear solves keep the exact inverse's recursion roots within a radius (module docstring)
        self.stable_inverse = bool(stable_inverse)
        self.inverse_radius = None if inverse_radius is None else float(inverse_radius)
        if self.stable_inverse:
            check_stable_inverse(model, inverse_radius)

    def record_radius(self, record) -> float:
        """The largest root modulus allowed on a fit record: ``inverse_radius``, or by default
        exp(-dt / T) with T the fit records' shortest drive period (``DataScale.time``): an input error
        of the exact inverse decays by e within that period, before the reference reverses again."""
        if self.inverse_radius is not None:
            return self.inverse_radius
        return math.exp(-record.dt / self.problem.scale.time)

    # --- the stable-inverse constraint ---------------------------------------
    def inverse_constraints(self, nonlinear: np.ndarray) -> InverseConstraints | None:
        """The Schur-Cohn rows at the operating points of the fit records (``inverse_recursion_rows``
        over each whole record: the exact inverse runs from rest, through the transient the scored
        window follows) and at every operating point an input within the input range can reach
        (``inverse_recursion_cover``; ``record`` is then len(records)) for a nonlinear parameter
        vector; None when unconstrained."""
        if not self.stable_inverse:
            return None
        p = self.problem
        nl = {n: float(v) for n, v in zip(self.nonlinear_names, np.asarray(nonlinear, dtype=float).ravel())}
        parts = [self.model.inverse_recursion_rows(r.u, r.dt, nl, None, p.input_range) for r in p.records]
        radius = [self.record_radius(r) for r in p.records]
        # every operating point an input within the input range reaches, at each sample time of the
        # records (the inverse runs at the rate the model was identified at), the tightest radius there
        for dt in sorted({float(r.dt) for r in p.records}):
            parts.append(self.model.inverse_recursion_cover(dt, nl, p.input_range))
            radius.append(min(self.record_radius(r) for r in p.records if float(r.dt) == dt))
        rows = type(parts[0]).stack(parts)
        record = np.concatenate([np.full(part.sample.size, m) for m, part in enumerate(parts)])
        rho = np.array(radius)[record][:, None]
        c0, c1, c2 = rho * rho * rows.c0, rho * rows.c1, rows.c2
        G = np.concatenate([c0 - c2, c0 + c2, c0 + c2 - c1, c0 + c2 + c1])
        return InverseConstraints(G, np.zeros(G.shape[0]), rows, record, rho[:, 0])

    # --- design matrices ---------------------------------------------------
    def _as_sets(self, nonlinear_sets) -> np.ndarray:
        sets = np.asarray(nonlinear_sets, dtype=float)
        return sets.reshape(1, len(self.nonlinear_names)) if sets.ndim < 2 else sets

    def blocks(self, nonlinear_sets: np.ndarray) -> list[np.ndarray]:
        """Per fit record, the unweighted regressors on its scored rows for each
        set: a list of (n_sets, n_m, n_linear) arrays. Counts the evaluations."""
        sets = self._as_sets(nonlinear_sets)
        p = self.problem

        out = [self.model.windowed_regressors_batch(r.u, r.dt, sets, r.scored, p.input_range) for r in p.records]
        p.n_evaluations += sets.shape[0]
        return out

    def designs(self, nonlinear_sets: np.ndarray) -> np.ndarray:
        """Weighted stacked design matrices A (rows sqrt(k_m/n_m) Phi_m), (n_sets, n_rows, n_linear)."""
        blocks = self.blocks(nonlinear_sets)
        return np.concatenate([w * B for w, B in zip(self.problem.row_weights, blocks)], axis=1)

    def record_designs(self, nonlinear: Mapping[str, float]) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """Per fit record: (Phi on its scored rows, measured y there, k_m / n_m), unweighted."""
        p = self.problem
        sets = np.array([[float(nonlinear[n]) for n in self.nonlinear_names]])
        return [(self.model.windowed_regressors_batch(r.u, r.dt, sets, r.scored, p.input_range)[0],
                 r.y[r.scored].copy(), r.weight / r.n_scored) for r in p.records]

    # --- the linear solve ----------------------------------------------------
    def solve_blocks(self, blocks: list[np.ndarray], accurate: bool = False,
                     constraints: InverseConstraints | None = None) -> LinearSolution:
        """Exact (regularised, bounded) least squares for one set's per-record regressors.

        Works on the column-scaled matrix A_s = A D^-1 (unit-norm columns) of
        the weighted stack A = [w_m Phi_m]. Fast path (the search): eigen-
        decomposition of A_s^T A_s, accumulated per record, nothing stacked;
        its error (~cond^2 * 1e-16 in the weakest direction) changes the
        fitness only at second order. ``accurate`` (the reported optimum): a
        Householder QR of [A_s, b] and the SVD of its small triangle
        (condition numbers exact up to ~1e16); there, directions the data do
        not determine (singular value below ``linear.UNDETERMINED_TOL`` * s_max)
        are found and their parameters fixed at 0 (``linear.dependent_columns``, columns kept in
        ``column_priority``). In both paths, next to an intercept, a column nearly constant on the
        scored rows is fixed at 0 (``varying_columns``). A model output that is not
        finite gives an infinite fitness and is counted in the problem's ``n_nonfinite``.
        ``constraints`` (``inverse_constraints``): the solve keeps G x >= h and the bounds
        (``linear.spectral_inequality_solve``) when the unconstrained solution breaks them.
        """
        keep = self.varying_columns(blocks)
        sol = self._solve(blocks, accurate, None if keep.all() else keep, constraints)
        sol.nearly_constant = [n for n, k in zip(self.linear_names, keep) if not k]
        if not (accurate and sol.n_undetermined and math.isfinite(sol.fitness)):
            return sol
        cols = np.flatnonzero(keep)
        A = np.concatenate([wm * Phi[:, cols] for wm, Phi in zip(self.problem.row_weights, blocks)])
        dependent = dependent_columns(A, self.column_priority([Phi[:, cols] for Phi in blocks]))
        if not dependent.any():
            return sol
        keep[cols[dependent]] = False
        reduced = self._solve(blocks, True, keep, constraints)
        if not reduced.fitness <= sol.fitness * (1.0 + FREE_FIX):  # the bounds determine those directions
            return sol
        reduced.condition_number_full = sol.condition_number
        reduced.nearly_constant = sol.nearly_constant
        return reduced

    @staticmethod
    def column_groups(blocks: list[np.ndarray]) -> np.ndarray:
        """Per column: 0 an intercept (1 on every scored row), 2 nearly constant on the scored rows (spread
        below ``NEAR_CONSTANT`` of its largest magnitude), 1 the others."""
        stacked = np.concatenate(blocks)
        ones = np.all(stacked == 1.0, axis=0)
        span = np.ptp(stacked, axis=0) if stacked.shape[0] else np.zeros(stacked.shape[1])
        constant = span <= NEAR_CONSTANT * np.max(np.abs(stacked), axis=0, initial=0.0)
        return np.where(ones, 0, np.where(constant, 2, 1))

    def varying_columns(self, blocks: list[np.ndarray]) -> np.ndarray:
        """The columns solved for: all but those nearly constant on the scored rows, when the design has
        an intercept. Such a column (a play whose threshold lies above the scored input's span moves only
        through the rate envelopes, by a fraction of its level) repeats the intercept there up to that
        fraction; a weight fitted to the remainder multiplies a level that the intercept absorbs in the
        scored windows but not where the column differs (from rest, before the play first turns)."""
        group = self.column_groups(blocks)
        if not np.any(group == 0):
            return np.ones(group.size, dtype=bool)
        return group != 2

    def column_priority(self, blocks: list[np.ndarray]) -> np.ndarray:
        """The order in which columns are kept when some must be fixed (``linear.dependent_columns``):
        an intercept first, then the columns that vary on the scored rows, then those nearly constant
        there, each group in the model's order."""
        group = self.column_groups(blocks)
        return np.lexsort((np.arange(group.size), group))

    def _solve(self, blocks: list[np.ndarray], accurate: bool, keep: np.ndarray | None,
               constraints: InverseConstraints | None = None) -> LinearSolution:
        """``solve_blocks`` on the columns ``keep`` (None: all); the others are fixed at 0 (or the bound
        nearest 0) and their contribution taken off the data."""
        w = self.problem.row_weights
        n = len(self.linear_names)
        names = list(self.linear_names)
        lo, hi = self.lin_lower, self.lin_upper
        ys = self._ys
        b = self.b
        x_fixed = np.zeros(0)
        Gc = hc = None  # the constraint rows (G is the Gram matrix below)
        if constraints is not None:
            Gc, hc = constraints.G, constraints.h
        if keep is not None:
            x_fixed = np.clip(0.0, lo[~keep], hi[~keep])
            if np.any(x_fixed != 0.0):
                ys = [y - Phi[:, ~keep] @ x_fixed for Phi, y in zip(blocks, ys)]
                b = np.concatenate([wm * y for wm, y in zip(w, ys)])
            if Gc is not None:
                hc = hc - Gc[:, ~keep] @ x_fixed
                Gc = Gc[:, keep]
            blocks = [np.ascontiguousarray(Phi[:, keep]) for Phi in blocks]
            names = [nm for nm, k in zip(names, keep) if k]
            lo, hi = lo[keep], hi[keep]
        blown_up = LinearSolution(np.zeros(n), math.inf, np.full(self.b.size, np.inf), math.inf, False, 0.0, False,
                                  [])

        def times(x):  # residual blocks w_m (Phi_m x - y_m)
            return [wm * (Phi @ x - y) for wm, Phi, y in zip(w, blocks, ys)]

        if accurate:
            A = np.concatenate([wm * Phi for wm, Phi in zip(w, blocks)])
            D = column_norms(A)
            if not np.all(np.isfinite(D)):
                self.problem.n_nonfinite += 1
                return blown_up
            ev, V, rhs = spectrum_from_qr(A, b, column_scale=D)
        else:
            with np.errstate(over="ignore", invalid="ignore"):
                G = sum((wm * wm) * (Phi.T @ Phi) for wm, Phi in zip(w, blocks))
                Atb = sum((wm * wm) * (Phi.T @ y) for wm, Phi, y in zip(w, blocks, ys))
            if not (np.all(np.isfinite(G)) and np.all(np.isfinite(Atb))):
                self.problem.n_nonfinite += 1
                return blown_up
            D = np.sqrt(np.diag(G)).copy()
            D[~(D > 0)] = 1.0
            ev, V, rhs = spectrum_from_gram(G / np.outer(D, D), Atb / D)
        spec = solve_spectrum(ev, V, rhs, self.max_condition)
        ev, cond, alpha2, regularised = spec.ev, spec.condition_number, spec.alpha2, spec.regularised
        ev_max = float(ev[0]) if ev.size else 0.0
        denom, safe = spec.denominators, spec.kept
        x = spec.x_scaled / D
        bounded = False
        inverse_constrained, active, violation = False, np.zeros(0, dtype=int), 0.0
        if Gc is not None:
            # the constraint rows and the bounds, as one system G_all x >= h_all
            finite_lo, finite_hi = np.isfinite(lo), np.isfinite(hi)
            eye = np.eye(x.size)
            G_all = np.concatenate([Gc, eye[finite_lo], -eye[finite_hi]])
            h_all = np.concatenate([hc, lo[finite_lo], -hi[finite_hi]])
            if np.any(G_all @ x < h_all):
                solved = spectral_inequality_solve(V[:, safe], denom[safe], rhs[safe], D, G_all, h_all)
                if solved is not None:
                    x = solved
            size = np.abs(G_all) @ np.abs(x) + np.abs(h_all)  # the size of the terms each row sums
            slack = (G_all @ x - h_all) / np.where(size > 0, size, 1.0)
            violation = float(max(0.0, -np.min(slack, initial=0.0)))
            at = np.flatnonzero(slack <= ACTIVE_SLACK)
            active = at[at < Gc.shape[0]]
            inverse_constrained = active.size > 0
            bounded = bool(np.any(at >= Gc.shape[0]))
            x = np.clip(x, lo, hi)
        elif np.any(x < lo) or np.any(x > hi):
            bounded = True
            # min ||A_s xs - b||^2 + alpha2 ||xs||^2 as the small system M xs ~ c
            root = np.sqrt(denom[safe])
            M = (V[:, safe] * root).T
            c = rhs[safe] / root
            res = lsq_linear(M, c, bounds=(lo * D, hi * D), method="bvls", tol=1e-12)
            x = np.clip(res.x / D, lo, hi)
        r = np.concatenate(times(x))
        fit = float(r @ r)
        weak = []
        if regularised:
            for k in np.flatnonzero(ev < alpha2):
                load = V[:, k] / D  # direction in parameter units
                load = load / np.max(np.abs(load))
                top = np.argsort(-np.abs(load))[:4]
                weak.append((math.sqrt(ev[k] / ev_max) if ev_max > 0 else 0.0,
                             {names[i]: float(load[i]) for i in top if abs(load[i]) >= 0.05}))
        scale = self.output_scale
        fixed: dict = {}
        if keep is not None:
            x_all = np.zeros(n)
            x_all[keep] = x
            x_all[~keep] = x_fixed
            fixed = {nm: float(v * scale) for nm, v in zip(np.array(self.linear_names)[~keep], x_fixed)}
            x = x_all
        return LinearSolution(x * scale, fit * scale * scale, r, cond, regularised,
                              math.sqrt(alpha2 / ev_max) if regularised else 0.0, bounded, weak,
                              undetermined_count(ev) if accurate else 0, fixed,
                              inverse_constrained=inverse_constrained, active_constraints=active,
                              constraint_violation=violation)

    def _Atb(self, blocks):
        return sum((wm * wm) * (Phi.T @ y) for wm, Phi, y in zip(self.problem.row_weights, blocks, self._ys))

    def solve_design(self, A: np.ndarray, accurate: bool = False) -> LinearSolution:
        """The linear solve for a weighted stacked design matrix A (as from ``designs``)."""
        w = self.problem.row_weights
        blocks, row = [], 0
        for wm, r in zip(w, self.problem.records):
            blocks.append(A[row:row + r.n_scored] / wm)
            row += r.n_scored
        return self.solve_blocks(blocks, accurate)

    def solve(self, nonlinear: Mapping[str, float] | np.ndarray, accurate: bool = True) -> LinearSolution:
        """The linear solve given the nonlinear parameters (a mapping, or a vector in their order)."""
        if isinstance(nonlinear, Mapping):
            missing = [n for n in self.nonlinear_names if n not in nonlinear]
            if missing:
                raise IdentificationError(f"varpro solve: missing nonlinear parameter(s) {', '.join(missing)}")
            vec = np.array([float(nonlinear[n]) for n in self.nonlinear_names])
        else:
            vec = np.asarray(nonlinear, dtype=float).reshape(len(self.nonlinear_names))
        return self.solve_blocks([B[0] for B in self.blocks(vec[None])], accurate=accurate,
                                 constraints=self.inverse_constraints(vec))

    def projected_batch(self, nonlinear_sets: np.ndarray) -> list[LinearSolution]:
        """Linear solves for many nonlinear sets; the best fitness goes to the history."""
        sets = self._as_sets(nonlinear_sets)
        n_lin = len(self.linear_names)
        chunk = max(1, MAX_BATCH_ELEMENTS // max(1, self.problem.n_rows * n_lin))
        sols = []
        for a in range(0, sets.shape[0], chunk):
            blocks = self.blocks(sets[a:a + chunk])
            sols.extend(self.solve_blocks([B[i] for B in blocks], constraints=self.inverse_constraints(sets[a + i]))
                        for i in range(blocks[0].shape[0]))
        self.problem.note(min(s.fitness for s in sols))
        return sols

    def full_vector(self, nonlinear: np.ndarray, linear: np.ndarray) -> np.ndarray:
        x = np.empty(len(self.model.param_names))
        x[self.nl_idx] = nonlinear
        x[self.lin_idx] = linear
        return x


def run(problem: Problem, seed: int | None, start: Mapping[str, float] | None, **options) -> dict:
    """Identify by variable projection; returns params, diagnostics and notes."""
    opts = {**OPTIONS, **options}
    sep = SeparableProblem(problem, opts["max_condition"], opts["stable_inverse"], opts["inverse_radius"])
    x_start = problem.start_vector(start)
    d = len(sep.nonlinear_names)
    diag: dict = {"n_nonlinear": d, "n_linear": len(sep.linear_names)}
    if d == 0:  # a purely linear model: the final solve below is the whole identification
        best_nl = np.zeros(0)
        diag["local_searches"] = []
    else:
        # the search runs in coordinates s: log z for parameters declared log-scale (bounds > 0), else z
        flags = {p.name: p.log_scale for p in problem.model.parameters(problem.scale)}
        logs = np.array([flags.get(n, False) for n in sep.nonlinear_names]) & (sep.nl_lower > 0)

        def to_s(z):
            return np.where(logs, np.log(np.where(logs, z, 1.0)), z)

        def from_s(v):
            return np.where(logs, np.exp(np.where(logs, v, 0.0)), v)

        lo, hi = to_s(sep.nl_lower), to_s(sep.nl_upper)
        free = hi > lo  # a nonlinear parameter fixed by equal bounds is not searched
        width = np.where(free & np.isfinite(hi - lo), hi - lo, 1.0)
        cands = [np.clip(to_s(np.clip(x_start[sep.nl_idx], sep.nl_lower, sep.nl_upper)), lo, hi)]
        if opts["n_candidates"] > 0:
            if not np.all(np.isfinite(hi - lo)):
                bad = [n for n, ok in zip(sep.nonlinear_names, np.isfinite(hi - lo)) if not ok]
                raise IdentificationError(
                    f"method 'varpro' on model {problem.model.name!r}: candidate starts need finite bounds for "
                    f"{', '.join(bad)} (give bounds, or n_candidates=0)")
            halton = qmc.Halton(d, scramble=True, seed=np.random.default_rng(seed))
            cands.extend(lo + halton.random(int(opts["n_candidates"])) * (hi - lo))
        cands = np.array(cands)
        sols = sep.projected_batch(from_s(cands))
        order = np.argsort([s.fitness for s in sols], kind="stable")
        searches = []
        best_nl, best_f = from_s(cands[order[0]]), sols[order[0]].fitness
        step = (opts["fd_step"] * width)[free]
        base = cands[order[0]].copy()

        def full(zf):
            z = base.copy()
            z[free] = zf
            return z

        def embed(Zf):  # free coordinates -> search coordinates of every nonlinear parameter
            Z = np.repeat(base[None], Zf.shape[0], axis=0)
            Z[:, free] = Zf
            return Z

        ends: list[tuple[int, np.ndarray]] = []  # (search index, optimum) of finished searches
        projected = CachedResidual(lambda zf: sep.projected_batch(from_s(full(zf))[None])[0].residuals)

        def residual(zf):
            z = full(zf)
            for j, e in ends:
                if np.max(np.abs(z - e) / width) < opts["merge_radius"]:
                    raise _SameBasin(j)
            return projected(zf)

        def residual_batch(Zf):
            return np.array([s.residuals for s in sep.projected_batch(from_s(embed(Zf)))])

        def jacobian(zf):
            # C order, as scipy's trust region has always been given it here (BLAS sums in layout order)
            return np.ascontiguousarray(forward_difference(residual_batch, zf, residual(zf), step, hi[free]))

        if not free.any():
            order = order[:0]
        for k in order[: max(1, int(opts["n_starts"]))]:
            if not math.isfinite(sols[k].fitness):  # the model gave no finite output there
                continue
            base = cands[k].copy()
            n0 = problem.n_evaluations
            entry = {"start": [float(v) for v in from_s(cands[k])], "start_fitness": float(sols[k].fitness)}
            try:
                res = least_squares(residual, base[free], jac=jacobian, bounds=(lo[free], hi[free]), method="trf",
                                    x_scale=width[free], ftol=opts["tol"], xtol=opts["tol"], gtol=opts["tol"],
                                    max_nfev=int(opts["max_nfev"]))
            except _SameBasin as same:
                j = same.args[0]
                entry.update(end=searches[j]["end"], fitness=searches[j]["fitness"], status=-2,
                             message=f"stopped: reached the neighbourhood of search {j + 1}'s optimum",
                             n_evaluations=problem.n_evaluations - n0)
                searches.append(entry)
                continue
            f = float(2.0 * res.cost) * sep.output_scale**2
            end = full(res.x)
            entry.update(end=[float(v) for v in from_s(end)], fitness=f, status=int(res.status),
                         message=str(res.message), n_evaluations=problem.n_evaluations - n0)
            searches.append(entry)
            ends.append((len(searches) - 1, end))
            if f < best_f:
                best_nl, best_f = from_s(end), f
        diag["local_searches"] = searches
    final = sep.solve(best_nl, accurate=True)
    problem.note(final.fitness)
    x = sep.full_vector(best_nl, final.linear)
    diag.update(condition_number=final.condition_number, regularised=final.regularised, ridge=final.ridge,
                bounded_linear_solve=final.bounded, max_condition=sep.max_condition)
    notes = []
    if final.fixed:
        diag["undetermined"] = dict(final.fixed)
        rank = [n for n in final.fixed if n not in final.nearly_constant]
        if final.nearly_constant:
            notes.append(
                f"varpro: {', '.join(final.nearly_constant)}: regressor(s) nearly constant on the scored rows (spread "
                f"below {NEAR_CONSTANT:g} of the level) next to the intercept: the data determine their weights only "
                "through that spread while the level trades with the intercept; fixed at 0")
        if rank:
            diag["condition_number_all_columns"] = final.condition_number_full
            notes.append(
                f"varpro: the scored data do not determine {', '.join(rank)} (the column-scaled design has condition "
                f"number {final.condition_number_full:.3g}, a direction with singular value below "
                f"{UNDETERMINED_TOL:g} * s_max): fixed at {', '.join(f'{final.fixed[n]:g}' for n in rank)}, the rest "
                f"solved without (condition number {final.condition_number:.3g})")
    if final.regularised:
        dirs = "; ".join(
            " ".join(f"{v:+.2f}*{n}" for n, v in load.items()) + f" (s/s_max {sv:.1e})"
            for sv, load in final.weak_directions
        )
        notes.append(
            f"varpro: linear solve regularised: the column-scaled design matrix has condition number "
            f"{final.condition_number:.3g} > {sep.max_condition:.3g}; a ridge alpha = s_max/{sep.max_condition:.3g} "
            f"damps its weakest direction(s), which the data barely determine: {dirs}"
        )
        diag["weak_directions"] = [{"relative_singular_value": sv, "loadings": load}
                                   for sv, load in final.weak_directions]
    if final.bounded and not sep.stable_inverse:
        notes.append("varpro: the unconstrained linear solution left the bounds; solved with bounds (lsq_linear)")
    if sep.stable_inverse:
        stable_inverse_report(sep, best_nl, final, diag, notes)
    return {"x": x, "diagnostics": diag, "notes": notes}


def recursion_roots(c0: np.ndarray, c1: np.ndarray, c2: np.ndarray) -> np.ndarray:
    """The largest root modulus of c0 z^2 + c1 z + c2 per row (inf where c0 = 0 and c1 or c2 is not)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        b, c = c1 / c0, c2 / c0
        disc = b * b - 4.0 * c
        sq = np.sqrt(np.abs(disc))
        rho = np.where(disc >= 0.0, np.maximum(np.abs(-b + sq), np.abs(-b - sq)) / 2.0, np.sqrt(np.abs(c)))
    return np.where(c0 != 0.0, rho, np.where((c1 != 0.0) | (c2 != 0.0), np.inf, 0.0))


def stable_inverse_report(sep: SeparableProblem, nonlinear: np.ndarray, final: LinearSolution, diag: dict,
                          notes: list) -> None:
    """What the stable-inverse constraint did at the optimum, into the diagnostics and notes (always: a
    constraint that held without being needed is said too)."""
    cons = sep.inverse_constraints(nonlinear)
    theta = final.linear
    rows = cons.rows
    roots = recursion_roots(rows.c0 @ theta, rows.c1 @ theta, rows.c2 @ theta)
    files = [r.file for r in sep.problem.records]
    weights = [n for n in sep.linear_names if n.startswith("a")]
    active = [cons.describe(int(i), files, weights) for i in final.active_constraints]
    largest = float(np.max(roots, initial=0.0))
    excess = float(np.max(roots / cons.radius, initial=0.0))  # largest root relative to its allowed radius
    radii = sorted({float(v) for v in cons.radius})
    from_records = int(np.sum(cons.record < len(files)))
    lo, hi = map(float, sep.problem.input_range)
    diag["stable_inverse"] = {
        "inverse_radius": radii, "operating_points": int(rows.sample.size),
        "constrained_points": f"the fit records' operating points and {RANGE_COVER} [{lo:g}, {hi:g}]",
        "operating_points_fit_records": from_records,
        "operating_points_input_range": int(rows.sample.size) - from_records,
        "constraint_rows": int(cons.G.shape[0]), "largest_root_at_operating_points": largest,
        "largest_root_relative_to_radius": excess,
        "active": active, "n_active": len(active), "largest_violation": final.constraint_violation}
    kinds = {}
    for a in active:
        kinds[a["condition"]] = kinds.get(a["condition"], 0) + 1
    # the conditions are what the solve holds, to rounding; a double root moves by the square root of that
    held = (f"the conditions hold to {final.constraint_violation:.1e} relative"
            if final.constraint_violation <= ACTIVE_SLACK else
            f"does NOT hold: a condition is violated by {final.constraint_violation:.3g} relative")
    summary = ", ".join(f"{n} x {k}" for k, n in kinds.items()) or "none"
    notes.append(
        f"varpro: stable_inverse: linear solves constrained so that the exact inverse's error recursion "
        f"c0 e(k) + c1 e(k-1) + c2 e(k-2) = 0 has roots of modulus <= {', '.join(f'{v:.6g}' for v in radii)} at "
        f"{rows.sample.size} operating points ({from_records} of the fit records and {rows.sample.size - from_records} "
        f"covering {RANGE_COVER} [{lo:g}, {hi:g}]; {cons.G.shape[0]} rows); active at the optimum: {summary}; largest "
        f"root there {largest:.6g} ({held})")

