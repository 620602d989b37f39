"""Column-scaled linear least squares: the one home of the linear solve.

Separable least squares (``varpro``), the ablation and the diagnosis all
solve min ||A x - b|| for a design A whose columns differ by orders of
magnitude. The solve works on A_s = A D^-1 (unit-norm columns) through the
eigen-decomposition of A_s^T A_s = V diag(ev) V^T, obtained either

* accurately, from a Householder QR of [A_s, b] and the SVD of its small
  triangle (``spectrum_from_qr``: condition numbers exact up to ~1e16), or
* fast, from the Gram matrix accumulated block by block
  (``spectrum_from_gram``: error ~cond^2 * 1e-16 in the weakest direction).

``solve_spectrum`` then applies (A_s^T A_s + alpha^2 I)^+ with a ridge
alpha = s_max / max_condition when the condition number exceeds
``max_condition``, and drops the directions whose eigenvalue is below
``ev_cutoff`` * ev_max (minimum-norm solution there).

Directions the data do not determine. A direction of A_s whose singular value is below
``UNDETERMINED_TOL`` * s_max (the QR spectrum is exact to ~1e-16 * s_max, so this is six
decades above rounding) changes the fit by nothing the data can see: a regressor that is
constant on every scored row next to the intercept, two equal columns. No value of its
coefficient is supported by the data, yet it moves the model wherever the columns differ
(outside the scored rows: from rest, in transients). ``dependent_columns`` names the
parameters to fix there: a Householder QR of the columns in a stated priority order
(unpivoted), and a column whose diagonal |R_jj| is below ``UNDETERMINED_TOL`` * s_max (its
part not explained by the columns before it) is dependent; its coefficient is fixed and the
rest solved without it (``solve_fixing``).

Linear inequality constraints (``least_distance``, ``spectral_inequality_solve``): min ||A_s x - b||
(with the same ridge) subject to G x >= h is, in the eigenvectors of the solve, a least-distance
problem min ||z|| subject to E z >= f, solved as Lawson & Hanson's LDP through one non-negative
least squares (``scipy.optimize.nnls``; Lawson & Hanson, Solving Least Squares Problems, 1974,
ch. 23).

``scaled_lstsq(A, b)`` is the plain-matrix entry point: the truncated-SVD
minimum-norm solution of the column-scaled problem (numpy's ``lstsq`` on
A_s with ``rcond``), for one right-hand side or several.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.optimize import nnls

# directions whose eigenvalue of A_s^T A_s is below this fraction of the largest are dropped
DEFAULT_EV_CUTOFF = 1e-15
# a direction whose singular value of A_s is below this fraction of the largest is undetermined by the data
UNDETERMINED_TOL = 1e-10


def column_norms(A: np.ndarray) -> np.ndarray:
    """Euclidean norm of each column, zeros replaced by 1 for scaling (non-finite norms are kept: check them)."""
    with np.errstate(over="ignore"):
        D = np.sqrt(np.einsum("ij,ij->j", A, A))
    D[D == 0] = 1.0
    return D


def qr_triangle(A: np.ndarray, b2: np.ndarray, column_scale: np.ndarray | None = None) -> np.ndarray:
    """R of a Householder QR of [A / column_scale, b2] (LAPACK geqrf, as scipy.linalg.qr(mode="r")), its
    first n + m rows: the scaled matrix is written once, in Fortran order, and factored in place."""
    N, n = A.shape
    M = np.empty((N, n + b2.shape[1]), order="F")
    if column_scale is None:
        M[:, :n] = A
    else:
        np.divide(A, column_scale, out=M[:, :n])
    M[:, n:] = b2
    geqrf = scipy.linalg.get_lapack_funcs("geqrf", (M,))
    lwork = int(geqrf(M, lwork=-1, overwrite_a=1)[2][0].real)
    qr, _, _, info = geqrf(M, lwork=lwork, overwrite_a=1)
    if info < 0:
        raise ValueError(f"illegal value in argument {-info} of geqrf")
    return np.triu(qr[: min(N, n + b2.shape[1])])


def spectrum_from_qr(A_scaled: np.ndarray, b: np.ndarray,
                     column_scale: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ev, V, V^T A_s^T b) of A_s^T A_s, ev descending, from a QR of [A_s, b] (b 1-D or 2-D); with
    ``column_scale`` the first argument is the unscaled A and A_s = A / column_scale."""
    n = A_scaled.shape[1]
    b2 = b.reshape(b.shape[0], -1)
    R = qr_triangle(A_scaled, b2, column_scale)
    U, s, Vt = np.linalg.svd(R[:n, :n])  # A_s = Q U S V^T
    qtb = R[:n, n:] if b.ndim == 2 else R[:n, n]
    rhs = (s[:, None] if b.ndim == 2 else s) * (U.T @ qtb)
    return s * s, Vt.T, rhs


def spectrum_from_gram(G_scaled: np.ndarray, Atb_scaled: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ev, V, V^T A_s^T b) from the scaled Gram matrix A_s^T A_s and A_s^T b, ev descending."""
    ev, V = np.linalg.eigh(G_scaled)
    ev, V = ev[::-1], V[:, ::-1]
    return ev, V, V.T @ Atb_scaled


@dataclass
class SpectralSolve:
    """The scaled solution and what the solve did."""

    x_scaled: np.ndarray  # solution in scaled coordinates (divide by D for parameter units)
    ev: np.ndarray  # eigenvalues of A_s^T A_s, descending, clipped at 0
    V: np.ndarray
    rhs: np.ndarray
    condition_number: float  # of A_s
    regularised: bool  # the condition number exceeded max_condition
    alpha2: float  # ridge (0 when not regularised)
    kept: np.ndarray  # directions not dropped

    @property
    def denominators(self) -> np.ndarray:
        return self.ev + self.alpha2


def solve_spectrum(ev: np.ndarray, V: np.ndarray, rhs: np.ndarray, max_condition: float = math.inf,
                   ev_cutoff: float = DEFAULT_EV_CUTOFF) -> SpectralSolve:
    """Ridge above ``max_condition``; directions whose (ridged) eigenvalue is below ``ev_cutoff`` * ev_max
    (singular value below sqrt(ev_cutoff) * s_max) dropped; see the module docstring."""
    ev = np.maximum(ev, 0.0)
    ev_max = float(ev[0]) if ev.size else 0.0
    ev_min = float(ev[-1]) if ev.size else 0.0
    cond = math.sqrt(ev_max / ev_min) if ev_min > 0 else math.inf
    regularised = cond > max_condition
    alpha2 = ev_max / max_condition**2 if regularised else 0.0
    denom = ev + alpha2
    kept = denom > ev_max * ev_cutoff if ev_max > 0 else denom > 0
    c = np.zeros_like(rhs)
    c[kept] = rhs[kept] / denom[kept].reshape(-1, *([1] * (rhs.ndim - 1)))
    return SpectralSolve(V @ c, ev, V, rhs, cond, regularised, alpha2, kept)


def scaled_lstsq(A: np.ndarray, b: np.ndarray, rcond: float = 1e-10, max_condition: float = math.inf) -> np.ndarray:
    """Column-scaled least squares for a plain matrix: x minimising ||A x - b|| (b 1-D or 2-D), minimum norm
    in the directions whose scaled singular value is below ``rcond`` * s_max."""
    A = np.asarray(A, dtype=float)
    b = np.asarray(b, dtype=float)
    D = column_norms(A)
    if not (np.all(np.isfinite(D)) and np.all(np.isfinite(b))):
        raise ValueError("least_squares: the design matrix or the right-hand side is not finite")
    ev, V, rhs = spectrum_from_qr(A, b, column_scale=D)
    x = solve_spectrum(ev, V, rhs, max_condition, rcond**2).x_scaled
    return x / (D[:, None] if x.ndim == 2 else D)


def undetermined_count(ev: np.ndarray, tol: float = UNDETERMINED_TOL) -> int:
    """How many directions of A_s (eigenvalues ``ev`` of A_s^T A_s, descending) have a singular value below
    ``tol`` * s_max."""
    ev = np.maximum(np.asarray(ev, dtype=float), 0.0)
    if ev.size == 0 or not ev[0] > 0:
        return int(ev.size)
    return int(np.count_nonzero(ev < ev[0] * tol * tol))


def dependent_columns(A: np.ndarray, order: np.ndarray, column_scale: np.ndarray | None = None,
                      tol: float = UNDETERMINED_TOL) -> np.ndarray:
    """Boolean mask of the columns of A_s = A / column_scale that the columns before them in ``order`` (a
    permutation of the columns, highest priority first) already span to within ``tol`` * s_max: |R_jj| of a
    Householder QR of A_s[:, order]. Keeping the others leaves a design of full numerical rank."""
    A = np.asarray(A, dtype=float)
    D = column_norms(A) if column_scale is None else column_scale
    order = np.asarray(order, dtype=int)
    R = qr_triangle(A[:, order], np.zeros((A.shape[0], 0)), D[order])
    s_max = np.linalg.svd(R, compute_uv=False)[0] if R.size else 0.0
    diag = np.abs(np.diag(R))
    diag = np.concatenate([diag, np.zeros(order.size - diag.size)])  # fewer rows than columns
    dependent = np.zeros(A.shape[1], dtype=bool)
    dependent[order] = diag <= tol * s_max
    return dependent


def least_distance(E: np.ndarray, f: np.ndarray) -> np.ndarray | None:
    """The z of least norm with E z >= f, or None where no z satisfies the rows (Lawson & Hanson's
    LDP: the non-negative least squares min ||[E^T; f^T] v - e_{n+1}||, v >= 0, has residual r with
    r_{n+1} != 0 exactly when the rows are consistent, and then z = -r_{1..n} / r_{n+1}). Rows are
    scaled to unit norm first (the same constraints, a better conditioned NNLS)."""
    E = np.asarray(E, dtype=float)
    f = np.asarray(f, dtype=float)
    m, n = E.shape
    if m == 0 or np.all(f <= 0.0):
        return np.zeros(n)  # z = 0 satisfies every row
    norms = np.sqrt(np.einsum("ij,ij->i", E, E) + f * f)
    norms[norms == 0] = 1.0
    A = np.vstack([(E / norms[:, None]).T, (f / norms)[None]])
    target = np.zeros(n + 1)
    target[n] = 1.0
    v, _ = nnls(A, target, maxiter=50 * (m + n + 1))
    r = A @ v - target
    if not abs(r[n]) > 1e-12:
        return None
    return -r[:n] / r[n]


def spectral_inequality_solve(V: np.ndarray, denominators: np.ndarray, rhs: np.ndarray, D: np.ndarray,
                              G: np.ndarray, h: np.ndarray) -> np.ndarray | None:
    """x minimising ||A_s (D x) - b||^2 + alpha^2 ||D x||^2 subject to G x >= h, where A_s^T A_s +
    alpha^2 I = V diag(denominators) V^T and rhs = V^T A_s^T b (``solve_spectrum``'s kept directions:
    the solution stays in their span, as the unconstrained solve's does). With t = V^T (D x) the
    objective is ||root t - c||^2 + const (root = sqrt(denominators), c = rhs / root), so z = root t - c
    is a least-distance problem (``least_distance``). None where the rows are inconsistent."""
    root = np.sqrt(denominators)
    c = rhs / root
    T = (V / root) / D[:, None]  # x = T (z + c)
    E = G @ T
    f = h - E @ c
    z = least_distance(E, f)
    if z is None:
        return None
    return T @ (polish_least_distance(E, f, z) + c)


def polish_least_distance(E: np.ndarray, f: np.ndarray, z: np.ndarray, active_tol: float = 1e-8) -> np.ndarray:
    """``least_distance``'s z refined on its active set: the NNLS gives z to a precision that falls as
    ||z|| grows; the rows it holds as equalities (slack below ``active_tol`` of the row's size) define
    the least-norm z exactly (the minimum-norm solution of E_A z = f_A), kept when every row still
    holds at least as well as before."""
    size = np.abs(E) @ np.abs(z) + np.abs(f)
    size[size == 0] = 1.0
    slack = (E @ z - f) / size
    active = slack <= active_tol
    if not active.any():
        return z
    polished = np.linalg.lstsq(E[active], f[active], rcond=None)[0]
    worst = min(0.0, float(np.min(slack)))
    if float(np.min((E @ polished - f) / size)) >= worst - 1e-15:
        return polished
    return z
