"""Posterior of a partly linear model's parameters with emcee (``hysbench posterior``).

What is sampled. A model with a linear part (MRPIM: everything but gamma and
lambda) is y = Phi(theta_N) theta_L. The residuals of each fitted record
window are AR(1) noise with innovation sd sigma and coefficient phi (``noise
= "ar1"``), or independent (``"iid"``: phi = 0), see ``likelihood``. Given
(theta_N, sigma, phi) the linear parameters have a Gaussian conditional
posterior, so they are integrated out exactly and emcee's ensemble walks only
over (theta_N, log sigma, phi): four dimensions for MRPIM instead of 23. For
every state a walker visits, theta_L is drawn from its Gaussian conditional
and carried as the state's blob; the pairs (state, draw) are draws from the
joint posterior (a collapsed sampler: the acceptance ratio of the joint move
equals that of the marginal). The log-probability is vectorised over walkers:
one call builds the regressors of every walker (``windowed_regressors_batch``,
batched numba kernels) and the prewhitened Gram matrices (``whitened_gram``).

Priors (stated in every output, see ``Priors.describe``):

* theta_N: uniform on the identification bounds (the model's defaults scaled
  to the data, as ``identify`` uses them);
* sigma: log-uniform (Jeffreys) on [1e-9, 10] x max |y|;
* phi: uniform on (-1, 1) (a stationary AR(1));
* theta_L: independent normals centred on the middle of each parameter's
  identification bounds with sd = half their width (so +-1 sd is the search
  box of the identifiers). Weakly informative for what the data determine; for
  directions the data do not determine at all (MRPIM's operators whose
  threshold exceeds the input span are constant over every fitted window), the
  posterior is this prior, and the output says so.

Discrepancy and predictive calibration. The model's output gets a discrepancy term, a few
relaxations of the input integrated out with the linear parameters, and the predictive spread is
scaled per record frequency by c(f), set by in-sample and leave-one-identification-record-out
coverage: see ``discrepancy``. Non-finite model outputs are counted, never scored (``target.LogPosterior``).

Data. The fitted rows are the scored windows of the identification records
(what ``identify`` fits), every sample with the same weight: eq. 9's weights
k_m / n_m are an optimisation criterion, not a noise model. A record whose
input is periodic from its first sample and whose window starts after its
second period is simulated on a shortened input with the same window outputs
(``hysbench.data.periodic.periodic_proxy``); the shortcut is used only after checking on the record
that it reproduces the full record's regressors.

Start. ``identify(model, dataset, "varpro")`` gives theta_N and the noise start
comes from the residuals there. Because varpro minimises eq. 9 (weighted,
independent residuals), its optimum need not be near the mode of this
posterior: it is ranked with 64 Sobol points of the theta_N prior box in one
batched evaluation. From the best six (skipping those in the basin of a mode
already found), a few Newton steps on the log posterior (finite-difference
derivatives, batched) find a mode and its Laplace covariance. Every mode that
a valley separates from the others, within 10 log units of the best, is kept;
the walkers start split evenly between them, as draws from each one's Gaussian
(a diagonal ball from the curvature where the Hessian is not negative
definite). With two or more modes, the ensemble moves draw their helper walkers
from the moving walker's own mode, and a fifth of the moves are mode jumps that
carry a point's place in its mode's shape over to another mode; the shapes (each
mode's mean and covariance) are measured on a 200-step pilot run before the kept
chain starts (``modes``).

Convergence is measured, not assumed: emcee's integrated autocorrelation time
tau per parameter (linear ones from their draws), the chain after burn-in at
least ``TAU_FACTOR`` = 50 tau long, effective sample sizes, acceptance
fractions (a walker below 5 % is called stuck). ``sample_posterior`` stops
early once that holds and every parameter has ``min_ess`` effective samples,
else after ``max_steps``; burn-in is chosen automatically (see
``convergence``) unless given. Moves: emcee's differential evolution (0.8)
with its snooker variant (0.2) by default, whose autocorrelation times on
MRPIM were about 0.6 of the stretch move's.

Modules: ``target`` (segments, priors, the log posterior), ``discrepancy`` (the discrepancy term
and the held-out calibration), ``start`` (start candidates and one mode), ``modes`` (separated
modes: search, start, jumps), ``convergence``, ``backend`` (the chain file), ``run``
(``sample_posterior``, ``PosteriorRun``), ``predictive`` (bands, coverage, synthetic AR(1) data).
"""

from .backend import CHAIN_FORMAT, open_backend, settings_fingerprint
from .convergence import BURN_TAUS, MIN_ACCEPTANCE, TAU_FACTOR, Convergence, autocorr_times, convergence
from .discrepancy import DISCREPANCY_KINDS, Calibration, calibrate_scale, relaxation_columns, relaxation_times
from .predictive import ar1_noise, predictive, predictive_coverage, simulated_ar1_dataset
from .run import MOVES, PosteriorRun, sample_posterior
from .modes import (JUMP_SHARE, ModeJump, find_modes, mode_locations, mode_search_starts, nearest_mode, separated,
                    walkers_in_modes, with_mode_jumps)
from .start import find_mode, initial_walkers, noise_estimate, screen_candidates
from .target import NOISE_MODELS, LogPosterior, Priors, Segment, build_segments

__all__ = [
    "BURN_TAUS", "CHAIN_FORMAT", "DISCREPANCY_KINDS", "JUMP_SHARE", "MIN_ACCEPTANCE", "MOVES", "NOISE_MODELS",
    "TAU_FACTOR", "Calibration", "Convergence", "LogPosterior", "ModeJump", "PosteriorRun", "Priors", "Segment", "ar1_noise",
    "autocorr_times", "build_segments", "calibrate_scale", "convergence", "find_mode", "find_modes", "initial_walkers",
    "mode_locations", "mode_search_starts", "nearest_mode",
    "noise_estimate", "open_backend", "predictive", "predictive_coverage", "relaxation_columns",
    "relaxation_times", "sample_posterior", "screen_candidates", "separated", "settings_fingerprint",
    "simulated_ar1_dataset", "walkers_in_modes", "with_mode_jumps",
]
