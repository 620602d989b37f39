"""Classical Prandtl-Ishlinskii model (paper eq. 2-4), discretised like eq. 8:

    y(k) = p1 V(k) + sum_{i=1..N} a_i F_{r_i}[V](k) (+ c)
    F_r[V](k) = max(V(k) - r, min(V(k), F_r[V](k-1))),  F_r[V](0) = max(V(0) - r, min(V(0), 0))

with r_i = (i-1)/N ||V||_inf, no q V'' term and no envelopes. It is
rate-independent: the output path depends only on the input path.
``poly_order`` > 1 gives the polynomial-input variant (asymmetric loops).
"""

from __future__ import annotations

import numpy as np

from .errors import ModelError
from .inverse import Inversion, classical_pi_inverse
from .play_model import PlayOperatorModel


class ClassicalPI(PlayOperatorModel):
    name = "classical-pi"

    def __init__(self, n_operators: int = 13, poly_order: int = 1, offset: bool = True):
        super().__init__(
            n_operators=n_operators, poly_order=poly_order, q_term=False, envelopes=False, offset=offset
        )

    def get_hyperparameters(self) -> dict:
        return {"n_operators": self.n_operators, "poly_order": self.poly_order, "offset": self.offset}

    def invert_analytic(self, y_desired, dt: float, params, input_range) -> Inversion:
        """The analytic inverse (a P-I operator of the output; see models/inverse.py). Needs
        poly_order 1 and an increasing loading curve; the input it returns is not limited."""
        if self.poly_order != 1:
            raise ModelError(f"{self.name}: the analytic inverse needs poly_order=1 (got {self.poly_order}); "
                             "use invert (numerical)")
        if input_range is None:
            raise ModelError(f"{self.name}: the analytic inverse needs the fit's input_range")
        p = self.unpack(self.pack(params) if isinstance(params, dict) else params)
        y = np.ascontiguousarray(y_desired, dtype=float)
        r = self.thresholds(np.zeros(1), input_range)
        a = np.array([p[f"a{i}"] for i in range(1, self.n_operators + 1)])
        moving = r > 0  # F_0[u] = u: a zero threshold adds to the linear gain
        a0 = p["p1"] + float(np.sum(a[~moving]))
        h = 0.5 * r[moving]  # F_r[u] = P_{r/2}[u] - r/2, from the state r/2
        offset = (p["offset"] if self.offset else 0.0) - float(np.sum(a[moving] * h))
        u = classical_pi_inverse(y - offset, a0, a[moving], h, h)
        return Inversion(u, np.zeros(u.size, dtype=bool), method="analytic")
