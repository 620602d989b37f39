"""MRPIM: the modified rate-dependent Prandtl-Ishlinskii model (paper eq. 5-8).

    y(k) = p1 V + p2 V^2 + p3 V^3 + p4 V^4 + q V''(k) + sum_{i=1..13} a_i W_i(k)   (eq. 8)
    W_i(k) = max(h_l(k) - r_i, min(h_r(k), W_i(k-1)))                              (eq. 6)
    h_l = V - gamma |V'|,  h_r = V + lambda |V'|                                    (eq. 7)
    r_i = (i-1)/N ||V||_inf

V' = [V(k) - V(k-1)]/T as the paper states; V'' is the second backward
difference (our reading: the paper gives no scheme). ||V||_inf is taken over
``input_range``: the identification records' range when fitted, else the
simulated input's own (identical for the paper's protocol, where every record
spans 0.5-2.5 kV). W_i(0) starts from zero (see play_model).

An output offset c is added by default (a sensor's zero is arbitrary); preset
"paper" sets it to 0, so that configuration computes exactly eq. 8 with
Table 2. ``MRPIM(offset=False)`` has the paper's 20 parameters and no offset.
"""

from __future__ import annotations

from .errors import ModelError
from .play_model import PlayOperatorModel

# Table 2 of the paper (identified by MPSO).
PAPER_TABLE2 = {
    "gamma": 0.0323,
    "lambda": -0.0322,
    "p1": -2.0536,
    "p2": 5.5811,
    "p3": -1.5452,
    "p4": 0.1641,
    "q": 0.0254,
    "a1": -4.3668,
    "a2": 0.7119,
    "a3": -0.7480,
    "a4": 0.5184,
    "a5": -0.5119,
    "a6": 0.3491,
    "a7": -0.0132,
    "a8": 0.5967,
    "a9": 0.3318,
    "a10": 0.7624,
    "a11": 2.7350,
    "a12": 9.9937,
    "a13": -12.2643,
}


class MRPIM(PlayOperatorModel):
    """Modified rate-dependent P-I model; hyperparameters default to the paper's."""

    name = "mrpim"
    presets_available = ("paper",)

    def preset(self, name: str) -> dict[str, float]:
        if name != "paper":
            return super().preset(name)
        if (self.n_operators, self.poly_order, self.q_term, self.envelopes) != (13, 4, True, True):
            raise ModelError(
                "preset 'paper' needs n_operators=13, poly_order=4, q_term=True, envelopes=True; "
                f"this model is {self!r}"
            )
        params = dict(PAPER_TABLE2)
        if self.offset:
            params["offset"] = 0.0
        return params
