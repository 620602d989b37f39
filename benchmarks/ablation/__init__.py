"""Ablation of MRPIM: which of its parts earn their parameters on a dataset.

Variants of the registered ``mrpim`` model differ in four factors: the order
of the input polynomial (0..6), the q V'' term (on/off), the dynamic envelopes
(on/off; off is gamma = lambda = 0, the classical play operators) and the
number of play operators N. They are varied one factor at a time around a
reference (the paper's choice: order 4, q on, envelopes on, N = 13), plus the
full grid order x q x envelopes at the reference N. Identical variants are
fitted once.

Every variant is identified by variable projection (``identify(..., "varpro")``;
variants without envelopes, which have no nonlinear parameter, by varpro's
linear solve on shared regressors, see ``fit_once``) on the dataset's
identification records and scored on every record; then leave-one-frequency-out
cross-validation fits it, by the same procedure, on all records but those of
one frequency (``fit_on``) and predicts that frequency, for every frequency.

Definitions (also written into the JSON's ``definitions``):

* n_params: the model's parameters, output offset included (every variant has it).
* e_m, e_rms: eq. 10 per record, percent of the measured peak-to-peak over the
  scored window; ``*_e_rms`` is the mean over the records of that role,
  ``*_e_m`` the largest.
* cv_e_rms: mean over the left-out frequencies of the left-out records' e_rms.
  Each fitted record keeps the weight k_m the dataset gives it (Table 1's
  4, 1, 4, 1 for the identification frequencies and, in the protocol, 1 for
  the others); the weights are not renormalised when a frequency is left out
  (a common factor does not move eq. 9's minimum).
* AIC, BIC: a Gaussian likelihood with eq. 9's weighting on the identification
  records, i.e. residual r_mi ~ N(0, sigma^2 n_m / k_m) independently, sigma^2
  at its maximum-likelihood value f / n (f: eq. 9 at the fit, n: number of scored
  samples). Then -2 ln L = n ln(2 pi f / n) + n - sum_m n_m ln(k_m / n_m), and
  AIC = -2 ln L + 2 k, BIC = -2 ln L + k ln n with k = the model's parameters + 1
  (sigma). Residuals are autocorrelated (model error is smooth and periodic),
  so the n samples carry far less than n independent pieces of information:
  ``n_effective`` (an AR(1) estimate, sum_m n_m (1 - rho_m) / (1 + rho_m) with
  rho_m the lag-1 autocorrelation of the reference variant's residuals) and
  ``aic_effective``/``bic_effective`` (the likelihood term scaled by
  n_effective / n) show how much that weakens the case for bigger models.

Speed: an MRPIM's play operators run from a record's first sample, but a
sampled periodic input (the protocol's records) makes their state periodic after
one period (the state map over one period is a composition of clamps, hence
idempotent). ``trim_history`` therefore drops whole periods before the scored
window, keeping at least one, when the input is periodic from the first sample
(checked); the regressors on the window are then the same (checked at run time,
and every full fit is re-scored on the untrimmed records).
"""

from .conclusions import conclusions, factor_name
from .criteria import compare, verdicts
from .fit import FullBounds, SharedColumns, evaluate_variant, fit_once
from hysbench.data.periodic import trim_history

from .history import check_trim
from .plan import (CV_FIT_OPTIONS, FACTORS, FULL_FIT_OPTIONS, N_OPERATORS, ORDERS, PAPER, TIE_RELATIVE,
                   AblationError, Variant, frequency_groups, plan_variants)
from .run import DEFINITIONS, run_ablation

__all__ = ["AblationError", "CV_FIT_OPTIONS", "DEFINITIONS", "FACTORS", "FULL_FIT_OPTIONS", "FullBounds",
           "N_OPERATORS", "ORDERS", "PAPER", "SharedColumns", "TIE_RELATIVE", "Variant", "check_trim", "compare",
           "conclusions", "evaluate_variant", "factor_name", "fit_once", "frequency_groups", "plan_variants",
           "run_ablation", "trim_history", "verdicts"]
