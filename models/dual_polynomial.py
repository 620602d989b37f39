"""Dual-polynomial hysteresis model (registry name ``dual-polynomial``).

The seed paper (Zou & Gu, Polymers 10 (2018) 525) cites as its ref. [29] a
model of DEA hysteresis by two polynomials, one for the increasing and one for
the decreasing branch of the loop (its text could not be checked from here).
We write the two order-n polynomials of the normalised input xi in [-1, 1]
(xi = -1 at the lower end of the input range, +1 at the upper end) as a
centre line M and a half-width H:

    P_rise(xi) = M(xi) - H(xi),      P_fall(xi) = M(xi) + H(xi)
    M(xi) = sum_{j=1..n} m_j xi^j,   H(xi) = (1 - xi^2) sum_{j=0..n-2} h_j xi^j
    y = c + M(xi) - s H(xi)

s = +1 while the input rises, -1 while it falls (held where it is constant,
+1 at the start). Any pair of order-n polynomials that meet at both ends of
the range has exactly this form (2n free numbers with the offset c), so the
two branches always close the major loop: the output is continuous at
reversals at the range's ends. ``branch_polynomials`` returns the two
polynomials' coefficients.

Continuity at reversals inside the range (minor loops, or records of smaller
amplitude than ``input_range``): the one-reversal memory of ``branches``: the
output starts the new branch from where it was and joins that branch linearly
in xi by the end of the range it moves towards. Outside the range H is held
at 0 (the loop is closed there) and M is extrapolated.

Hyperparameter ``order`` n >= 2 (default 4, the order the seed paper chose for
its own polynomial). Every parameter is linear; the model is rate-independent
and, as published, needs a new parameter set to follow another rate.

Inverse (``KernelInvertible.invert``): where it is not invertible. Each branch is a polynomial
of order n in xi (plus the memory's linear term in a minor loop): it is invertible where its
slope M' - s H' + memory keeps one sign. A fitted order-4 branch may flatten or turn back
(typically near the range's ends, where the data constrain it least); desired outputs behind
such a turn or beyond the branch's values within the input limits are clipped to the
nearest output the search visits and counted. Where two inputs give y_d the one nearest
the previous input is taken.
"""

from __future__ import annotations

import numpy as np

from .branches import BranchModel
from .hyperparameters import check_int


class DualPolynomial(BranchModel):
    name = "dual-polynomial"

    def __init__(self, order: int = 4, offset: bool = True):
        super().__init__(offset=offset)
        self.order = check_int(self.name, "order", order, 2, 12)

    def _centre_parameters(self):
        return [(f"m{j}", f"centre line M: coefficient of xi^{j}") for j in range(1, self.order + 1)]

    def _halfwidth_parameters(self):
        return [(f"h{j}", f"half-width H: coefficient of (1 - xi^2) xi^{j}") for j in range(self.order - 1)]

    def branch_polynomials(self, params) -> tuple[np.ndarray, np.ndarray]:
        """Coefficients (xi^0 ... xi^n, offset included) of P_rise + c and P_fall + c."""
        p = params if isinstance(params, dict) else self.unpack(params)
        n = self.order
        centre = np.zeros(n + 1)
        centre[0] = p.get("offset", 0.0)
        for j in range(1, n + 1):
            centre[j] = p[f"m{j}"]
        half = np.zeros(n + 1)
        for j in range(n - 1):  # (1 - xi^2) xi^j = xi^j - xi^(j+2)
            half[j] += p[f"h{j}"]
            half[j + 2] -= p[f"h{j}"]
        return centre - half, centre + half
