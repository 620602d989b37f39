"""Shared machinery of the two branch-switching models (``elliptical``,
``dual-polynomial``): the input normalised over its range, the direction of
travel, and one rule that keeps the output continuous at reversals.

Both models give the output on two branches of the normalised input
xi in [-1, 1] (xi = -1 at the range's lower end, +1 at its upper end):

    y = c + M(xi) - s H(xi)

with s = +1 while the input rises (ascending branch) and s = -1 while it
falls. M is the loop's centre line, H its half-width; H(+-1) = 0, so the two
branches meet at the ends of the range and the major loop is closed and
continuous.

Direction s(k): the sign of u(k) - u(k-1); where the input does not change,
the previous direction is kept; s(0) = +1 (the record is taken to start
rising, as the paper's drive does from its minimum).

Reversals inside the range (minor loops): a plain branch switch would jump by
2 H(xi_t). We keep the output continuous with a one-reversal memory: after a
reversal at xi_t, where the output was y_t, the new branch B is followed as

    y = B(xi) + (y_t - B(xi_t)) w(xi),
    w = (1 - xi) / (1 - xi_t)  rising,    w = (1 + xi) / (1 + xi_t)  falling,

clipped to [0, 1]: the offset from the major branch decays linearly to zero at
the end of the range the input is moving towards. A reversal at the range's
end (the major loop) leaves no offset, so there the model is exactly the
published two-branch form. Outside the range (an input beyond
``input_range``) H is evaluated at the clipped xi (the loop is closed there)
and M is extrapolated.

Every output sample is linear in the coefficients of M and H (the reversal
value y_t is itself such a combination), so the model is linear in all its
parameters: ``branch_regressors`` runs the rule on each basis function.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .base import DataScale, HysteresisModel, Parameter
from .errors import ModelError


def normalised_input(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """xi = (2x - (hi + lo)) / (hi - lo): -1 at lo, +1 at hi."""
    if not hi > lo:
        raise ModelError(f"input range must have positive width, got ({lo!r}, {hi!r})")
    return (2.0 * x - (hi + lo)) / (hi - lo)


@njit(cache=True)
def direction(u):
    """+1 rising, -1 falling; held where the input is constant; +1 at the start."""
    n = u.shape[0]
    s = np.empty(n, dtype=np.int8)
    cur = 1
    for k in range(n):
        if k > 0:
            d = u[k] - u[k - 1]
            if d > 0.0:
                cur = 1
            elif d < 0.0:
                cur = -1
        s[k] = cur
    return s


@njit(cache=True)
def branch_regressors(xi, s, centre_basis, halfwidth_basis):
    """Columns of y - c for unit coefficients: first M's basis, then H's.

    centre_basis (T, nm): basis of M at xi; halfwidth_basis (T, nh): basis of
    H at clip(xi). Column value on branch s: G or -s K, with the reversal
    memory of the module docstring.
    """
    n_t = xi.shape[0]
    nm = centre_basis.shape[1]
    nh = halfwidth_basis.shape[1]
    nc = nm + nh
    out = np.empty((n_t, nc))
    jump = np.zeros(nc)
    xi_t = 0.0
    for k in range(n_t):
        sk = s[k]
        if k > 0 and sk != s[k - 1]:
            # reversal between k-1 and k: offset of the output from the new branch at k-1
            xi_t = xi[k - 1]
            for j in range(nm):
                jump[j] = out[k - 1, j] - centre_basis[k - 1, j]
            for j in range(nh):
                jump[nm + j] = out[k - 1, nm + j] + sk * halfwidth_basis[k - 1, j]
        # decay weight of the memory
        if sk > 0:
            den = 1.0 - xi_t
            w = (1.0 - xi[k]) / den if den > 1e-12 else 0.0
        else:
            den = 1.0 + xi_t
            w = (1.0 + xi[k]) / den if den > 1e-12 else 0.0
        if w < 0.0:
            w = 0.0
        elif w > 1.0:
            w = 1.0
        for j in range(nm):
            out[k, j] = centre_basis[k, j] + jump[j] * w
        for j in range(nh):
            out[k, nm + j] = -sk * halfwidth_basis[k, j] + jump[nm + j] * w
    return out


# --- the shared model class ---------------------------------------------------
COEF_BOUND = 10.0  # |coefficient| <= COEF_BOUND * y (basis functions are O(1) on [-1, 1])


class BranchModel(HysteresisModel):
    """Base of ``elliptical`` and ``dual-polynomial``: every parameter is linear.

    Subclasses define the centre-line and half-width parameters and bases.
    Parameter order: centre coefficients, half-width coefficients, offset.
    """

    def __init__(self, offset: bool = True):
        self.offset = offset

    # subclasses -----------------------------------------------------------
    def _centre_parameters(self) -> list[tuple[str, str]]:
        raise NotImplementedError

    def _halfwidth_parameters(self) -> list[tuple[str, str]]:
        raise NotImplementedError

    def _linearised(self, u: np.ndarray) -> np.ndarray:
        """The input on which the loop is drawn (identity unless overridden)."""
        return u

    def _centre_basis(self, xi: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    @staticmethod
    def _powers(x: np.ndarray, first: int, last: int) -> np.ndarray:
        """Columns x^first ... x^last by repeated products (numpy's x**3 calls pow)."""
        out = np.empty((x.size, last - first + 1))
        col = np.ones_like(x)
        for j in range(last + 1):
            if j >= first:
                out[:, j - first] = col
            col = col * x
        return out

    def _halfwidth_basis(self, xi_clipped: np.ndarray) -> np.ndarray:
        raise NotImplementedError

    # interface ------------------------------------------------------------
    def declare_parameters(self, scale: DataScale) -> list[Parameter]:
        b = COEF_BOUND * scale.y
        params = [Parameter(n, 0.0, -b, b, True, d) for n, d in self._centre_parameters()]
        params += [Parameter(n, 0.0, -b, b, True, d) for n, d in self._halfwidth_parameters()]
        if self.offset:
            params.append(self.offset_parameter(scale))
        return params

    def normalised(self, u, input_range=None) -> np.ndarray:
        """xi: the (linearised) input mapped to [-1, 1] over ``input_range``."""
        u = np.ascontiguousarray(u, dtype=float)
        lo, hi = self._input_range(u, input_range)
        if not hi > lo:
            raise ModelError(
                f"model {self.name!r} needs an input that varies (or an input_range of positive width), "
                f"got range ({lo!r}, {hi!r})"
            )
        x_lo, x_hi = self._linearised(np.array([lo, hi]))
        return normalised_input(self._linearised(u), float(x_lo), float(x_hi))

    def regressors(self, u, dt: float, nonlinear=None, input_range=None) -> np.ndarray:
        u = self._check_input(u, dt)
        if nonlinear:
            raise ModelError(
                f"model {self.name!r} has no nonlinear parameters; got {sorted(nonlinear)}"
            )
        xi = self.normalised(u, input_range)
        G = np.ascontiguousarray(self._centre_basis(xi), dtype=float)
        K = np.ascontiguousarray(self._halfwidth_basis(np.clip(xi, -1.0, 1.0)), dtype=float)
        Phi = branch_regressors(xi, direction(u), G, K)
        if self.offset:
            Phi = np.concatenate((Phi, np.ones((u.size, 1))), axis=1)
        return Phi

    def simulate_batch(self, u, dt: float, param_sets, input_range=None) -> np.ndarray:
        P = self._check_param_sets(param_sets)
        Phi = self.regressors(u, dt, None, input_range)
        # the time loop is input-only (in branch_regressors); the parameter sets are one product
        return P @ Phi.T
