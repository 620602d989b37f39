"""Classical Prandtl-Ishlinskii model (paper eq. 2-4), discretised like eq. 8:

    y(k) = p1 V(k) + sum_{i=1..N} a_i F_{r_i}[V](k) (+ c)
    F_r[V](k) = max(V(k) - r, min(V(k), F_r[V](k-1))),  F_r[V](0) = max(V(0) - r, min(V(0), 0))

with r_i = (i-1)/N ||V||_inf, no q V'' term and no envelopes. It is
rate-independent: the output path depends only on the input path.
``poly_order`` > 1 gives the polynomial-input variant (asymmetric loops).
"""

from __future__ import annotations

from .play_model import PlayOperatorModel


class ClassicalPI(PlayOperatorModel):
    name = "classical-pi"

    def __init__(self, n_operators: int = 13, poly_order: int = 1, offset: bool = True):
        super().__init__(
            n_operators=n_operators, poly_order=poly_order, q_term=False, envelopes=False, offset=offset
        )

    def get_hyperparameters(self) -> dict:
        return {"n_operators": self.n_operators, "poly_order": self.poly_order, "offset": self.offset}
