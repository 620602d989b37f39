"""Elliptical hysteresis model (registry name ``elliptical``).

The seed paper (Zou & Gu, Polymers 10 (2018) 525) cites as its ref. [28] an
elliptical model of a tubular DEA: once the input is linearised, the DEA's
loops are symmetric and ellipse-like, and an ellipse describes them. The
text of [28] could not be checked from here (the seed text has no reference
list); the form below is the
standard one for an ellipse-shaped loop (the loop of any linear lag under a
sinusoid; Gu & Zhu, "Modeling of rate-dependent hysteresis in piezoelectric
actuators using a family of ellipses", Sens. Actuators A 165 (2011) 303-309,
cited from memory, describe piezo loops by ellipses of this kind with
frequency-dependent parameters; here one parameter set serves every
frequency, as the seed paper describes [28]):

    x   = L(u)                                  linearised input
    xi  = (2x - (x_max + x_min)) / (x_max - x_min)     in [-1, 1]
    y   = c + sum_{j=1..K} m_j xi^j - s b sqrt(1 - xi^2)

s = +1 while the input rises, -1 while it falls (held where it is constant,
+1 at the start). b > 0 is a counter-clockwise loop (output lags input: the
rising branch below the falling one); b is the loop's vertical half-opening
at the centre of the range. For xi = -cos(wt) (the paper's drive) this is
exactly y = c - m_1 cos(wt) - b sin(wt): an ellipse traversed once per period.

Linearisation L (hyperparameter ``linearise``): "square" uses x = u|u|,
which is u^2 for the DEA's unipolar drive (the Maxwell stress, hence the
actuation, goes with the square of the voltage) and stays monotone for a
bipolar piezo drive; "none" uses x = u.

Interpretations (see ``branches``): (x_min, x_max) is L of ``input_range``
(None: the input's own range); reversals inside the range keep the output
continuous by the one-reversal memory of ``branches`` (the published form
only covers the major loop, where the two coincide); outside the range the
ellipse term is 0. ``poly_order`` K = 1 is the published centre line; more
terms bend it. Every parameter is linear; one parameter set serves every
frequency, so the model is rate-independent by construction.

Inverse (``KernelInvertible.invert``): where it is not invertible. The ellipse has vertical
tangents at the range's ends: on the rising branch (K = 1) dy/dxi = m_1 + b xi / sqrt(1 - xi^2)
runs to -inf as xi -> -1, so for b > 0 the branch first dips below y(-1) and turns up only at
xi* = -m_1 / sqrt(m_1^2 + b^2) (the falling branch mirrors this at +1). Outputs below the
dip (above the crest) are out of reach: clipped to the nearest output and counted; an output
between y(-1) and the dip's bottom has two roots on the branch, and the search takes the
one nearest the previous input. More centre terms (K > 1) can add flat or turning stretches
inside the range; minor loops follow the memory rule, which scales the same shape.
"""

from __future__ import annotations

import numpy as np

from .branches import ELLIPSE, BranchModel
from .hyperparameters import check_choice, check_int

LINEARISATIONS = ("square", "none")


class Elliptical(BranchModel):
    name = "elliptical"
    halfwidth_kind = ELLIPSE

    def __init__(self, linearise: str = "square", poly_order: int = 1, offset: bool = True):
        super().__init__(offset=offset)
        self.linearise = check_choice(self.name, "linearise", linearise, LINEARISATIONS)
        self.poly_order = check_int(self.name, "poly_order", poly_order, 1, 8)

    def _centre_parameters(self):
        return [(f"m{j}", f"centre line: coefficient of xi^{j}") for j in range(1, self.poly_order + 1)]

    def _halfwidth_parameters(self):
        return [("b", "half-opening of the ellipse at mid-range (> 0: counter-clockwise loop)")]

    def _linearised(self, u):
        return u * np.abs(u) if self.linearise == "square" else u

    @property
    def square_input(self) -> bool:
        return self.linearise == "square"
