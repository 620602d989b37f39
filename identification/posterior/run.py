"""The run: ``sample_posterior`` (start, emcee, stopping rule, chain file) and its result."""

from __future__ import annotations

import json
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import emcee
import h5py
import numpy as np
from tqdm import tqdm

from hysbench.data.dataset import Dataset
from hysbench.models.base import HysteresisModel

from ..api import identify
from ..errors import IdentificationError
from .backend import open_backend, seconds_of, settings_fingerprint, store_start
from .convergence import TAU_FACTOR, Convergence, convergence
from .discrepancy import Calibration, calibrate_scale
from .modes import (JUMP_SHARE, PILOT_STEPS, ensemble_sampler, find_modes, jump_centres, mode_covariances,
                    mode_locations, mode_search_starts, nearest_mode, pilot_shapes, walkers_in_modes, with_mode_jumps)
from .start import noise_estimate, screen_candidates
from .target import LogPosterior


MOVES = {
    "stretch": lambda emcee: None,
    "de": lambda emcee: [(emcee.moves.DEMove(), 0.8), (emcee.moves.DESnookerMove(), 0.2)],
}


@dataclass
class PosteriorRun:
    """What ``sample_posterior`` returns; ``summary()`` gives the JSON body.

    Attributes
    ----------
    post : LogPosterior
        The target: the model, the records, the priors and the noise model.
    chain : numpy.ndarray
        The sampled coordinates (``post.coord_names``: nonlinear parameters, sigma, phi), shape
        (steps, walkers, d), every step including burn-in.
    draws : numpy.ndarray
        The linear parameters drawn at each state, shape (steps, walkers, p).
    log_prob : numpy.ndarray
        The log posterior of each state, shape (steps, walkers).
    conv : Convergence
        Burn-in, autocorrelation times and effective sample sizes of the chain.
    start : dict
        How the walkers started: the start ``method`` ("varpro" or "given"), its ``params``, the noise
        estimate, the posterior ``mode`` and ``modes`` found, ``seconds``.
    wall_seconds : float
        Wall time over every run that built the chain (resumed runs add up), s.
    sampling_seconds : float
        The part of ``wall_seconds`` spent in emcee, s.
    this_run_seconds : float
        Wall time of this call, s.
    resumed_from : int
        The steps read from the chain file before this call (0: a fresh chain).
    n_walkers : int
        The number of walkers.
    moves : str
        The emcee moves: "stretch" or "de".
    seed : int or None
        The seed of the start and of the sampler.
    dataset : str
        The dataset's name.
    chain_file : str or None
        The HDF5 chain file (None: kept in memory only).
    calibration : Calibration or None
        The predictive scale of the mode holding most kept states (None: not calibrated).
    mode_calibrations : list[Calibration or None]
        One per start mode (None: the mode holds no kept state).
    notes : list[str]
        Warnings in words (several modes, parameters cut off by a prior bound).
    names : list[str]
        The reported parameters: the model's, the discrepancy's, then sigma and phi (a property).
    """

    post: LogPosterior
    chain: np.ndarray
    draws: np.ndarray
    log_prob: np.ndarray
    conv: Convergence
    start: dict
    wall_seconds: float
    sampling_seconds: float
    this_run_seconds: float
    resumed_from: int
    n_walkers: int
    moves: str
    seed: int | None
    dataset: str
    chain_file: str | None
    calibration: Calibration | None = None
    mode_calibrations: list = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    # --- reported parameters: model order, then sigma and phi -------------------------
    @property
    def names(self) -> list[str]:
        """The reported parameters, in the order of ``samples`` and ``reported_tau``."""
        return list(self.post.param_names) + list(self.post.discrepancy_names) + ["sigma", "phi"]

    def samples(self, thin: int = 1) -> np.ndarray:
        """Kept draws of every reported parameter, flattened: (n, len(names))."""
        b = self.conv.burn
        ch = self.chain[b::thin]
        dr = self.draws[b::thin]
        nl, sigma, phi = self.post.split(ch.reshape(-1, ch.shape[-1]))
        dr = dr.reshape(-1, dr.shape[-1])
        full = self.post.full_params(nl, dr)
        return np.column_stack([full, dr[:, len(self.post.model_linear_names):], sigma, phi])

    def reported_tau(self) -> tuple[np.ndarray, np.ndarray]:
        """(tau, ess) in ``names`` order."""
        d_nl = len(self.post.nonlinear_names)
        p = len(self.post.model_linear_names)
        k_d = len(self.post.discrepancy_names)
        tau_c, tau_l = self.conv.tau[: self.post.ndim], self.conv.tau[self.post.ndim:]
        ess_c, ess_l = self.conv.ess[: self.post.ndim], self.conv.ess[self.post.ndim:]
        tau = np.full(len(self.names), np.nan)
        ess = np.full(len(self.names), np.nan)
        tau[self.post.nl_idx], ess[self.post.nl_idx] = tau_c[:d_nl], ess_c[:d_nl]
        tau[self.post.lin_idx], ess[self.post.lin_idx] = tau_l[:p], ess_l[:p]
        k = len(self.post.param_names)
        tau[k:k + k_d], ess[k:k + k_d] = tau_l[p:p + k_d], ess_l[p:p + k_d]
        k += k_d
        tau[k], ess[k] = tau_c[d_nl], ess_c[d_nl]
        if self.post.noise == "ar1":
            tau[k + 1], ess[k + 1] = tau_c[d_nl + 1], ess_c[d_nl + 1]
        return tau, ess

    def mode_locations(self) -> np.ndarray:
        """The separated modes the walkers started in (sampler coordinates, best first): (k, d)."""
        return mode_locations(self.post, self.start)

    def kept_states(self) -> np.ndarray:
        """The kept chain (after burn-in), flattened: (steps x walkers, d) sampler coordinates."""
        return self.chain[self.conv.burn:].reshape(-1, self.chain.shape[-1])

    def mode_of_kept(self) -> np.ndarray:
        """Index of the nearest start mode for every kept state (flattened like ``samples``)."""
        return nearest_mode(self.post, self.kept_states(), self.mode_locations())

    def mode_shares(self) -> list[float]:
        """Share of the kept states nearest to each start mode."""
        which = self.mode_of_kept()
        return [float(v) for v in np.bincount(which, minlength=max(1, len(self.mode_locations()))) / max(1, which.size)]

    def at_prior_bound(self) -> dict:
        """Nonlinear parameters with >= ``BOUND_SHARE`` of the kept states within ``BOUND_BAND`` of the
        prior's range from a bound: name -> {"bound", "value", "share"} (the prior cuts the posterior off)."""
        nl = self.post.split(self.kept_states())[0]
        lo, hi = self.post.priors.nonlinear_lower, self.post.priors.nonlinear_upper
        out = {}
        for name, (s_lo, s_hi), a, b in zip(self.post.nonlinear_names, bound_shares(nl, lo, hi), lo, hi):
            side = max((s_lo, "lower", a), (s_hi, "upper", b))
            if side[0] >= BOUND_SHARE:
                out[name] = {"bound": side[1], "value": float(side[2]), "share": float(side[0])}
        return out

    def modes_summary(self) -> list[dict]:
        """The start modes with their log posterior, walkers at the start and share of the kept states."""
        found = (self.start or {}).get("modes") or []
        return [{**m, "share_of_kept_states": share} for m, share in zip(found, self.mode_shares())]

    def main_mode(self) -> int:
        """The start mode holding most kept states."""
        return int(np.argmax(np.bincount(self.mode_of_kept())))

    def median_state(self, mode: int | None = None) -> tuple[np.ndarray, float, float] | None:
        """(theta_N, sigma, phi) at the posterior medians of the kept states in ``mode`` (default: the mode
        holding most of them; a coordinate-wise median across separated modes can fall in the valley
        between them); None if the mode holds no kept state."""
        which = self.mode_of_kept()
        ch = self.kept_states()[which == (int(np.argmax(np.bincount(which))) if mode is None else mode)]
        if not len(ch):
            return None
        nl, sigma, phi = self.post.split(np.median(ch, axis=0)[None])
        return nl[0], float(sigma[0]), float(phi[0])

    def predictive_scale(self, frequency_hz, mode: int | None = None) -> float:
        """The held-out calibration's scale of the predictive spread at a record's frequency; with ``mode``,
        that of the draws in that start mode (each mode is calibrated at its own median state)."""
        cal = self.calibration
        if mode is not None and mode < len(self.mode_calibrations) and self.mode_calibrations[mode] is not None:
            cal = self.mode_calibrations[mode]
        return 1.0 if cal is None else cal.scale_at(frequency_hz)

    def inside_fitted_range(self, frequency_hz) -> bool | None:
        """Whether a frequency lies within the identification records' frequency range (None: unknown, or the
        calibration has no frequency spread)."""
        cal = self.calibration
        if cal is None or cal.constant is not None:
            return None
        return cal.inside(frequency_hz)

    def parameter_table(self) -> dict:
        S = self.samples()
        tau, ess = self.reported_tau()
        q = np.quantile(S, [0.05, 0.5, 0.95], axis=0)
        out = {}
        for i, n in enumerate(self.names):
            out[n] = {"mean": float(np.mean(S[:, i])), "sd": float(np.std(S[:, i], ddof=1)),
                      "q05": float(q[0, i]), "q50": float(q[1, i]), "q95": float(q[2, i]),
                      "ess": _num(ess[i]), "tau": _num(tau[i])}
        return out

    def correlation(self) -> tuple[list[str], np.ndarray]:
        """Correlation matrix of the model parameters and the noise parameters that vary."""
        S = self.samples()
        keep = [i for i in range(S.shape[1]) if np.std(S[:, i]) > 0]
        return [self.names[i] for i in keep], np.corrcoef(S[:, keep], rowvar=False)

    def summary(self) -> dict:
        c = self.conv
        tau, ess = self.reported_tau()
        names, corr = self.correlation()
        return {
            "format": "hysbench-posterior/1",
            "dataset": self.dataset,
            "model": self.post.model.name,
            "hyperparameters": self.post.model.get_hyperparameters(),
            "noise_model": {"name": self.post.noise,
                            "description": ("stationary AR(1) residuals per record window, exact likelihood "
                                            "(Prais-Winsten)" if self.post.noise == "ar1"
                                            else "independent Gaussian residuals (phi = 0)")},
            "linear_parameters": "integrated out analytically (Gaussian conditional); drawn from it per state",
            "discrepancy": {"kind": self.post.discrepancy, "relaxation_times_s": [float(t) for t in self.post.taus],
                            "coefficients": list(self.post.discrepancy_names),
                            "description": ("sum_k c_k (L_k u - u): first-order relaxations of the input, "
                                            "integrated out with the linear parameters"
                                            if self.post.discrepancy == "relaxation" else "none")},
            "predictive_calibration": None if self.calibration is None else self.calibration.describe(),
            "predictive_calibration_per_mode": (
                [None if c is None else c.describe() for c in self.mode_calibrations]
                if len(self.mode_calibrations) > 1 else None),
            "nonfinite_model_outputs": {"log_posterior_evaluations": self.post.n_nonfinite,
                                        "singular_linear_precision": self.post.n_singular,
                                        "of_evaluations": self.post.n_evaluations},
            "converged": c.converged,
            "convergence_problems": c.problems,
            "ess_target": c.min_ess,
            "ess_target_met": c.ess_met,
            "min_ess": _num(np.nanmin(ess)) if np.any(np.isfinite(ess)) else None,
            "parameters": self.parameter_table(),
            "priors": self.post.priors.describe(),
            "sampler": {
                "package": "emcee", "walkers": self.n_walkers, "steps": c.n_steps, "burn_in": c.burn,
                "kept_steps": c.kept, "moves": self.moves, "sampled_coordinates": list(self.post.coord_names),
                "tau_max": _num(c.tau_max), "chain_length_in_tau": _num(c.length_in_tau),
                "tau_factor_required": TAU_FACTOR,
                "acceptance_fraction": {"mean": float(np.mean(c.acceptance)), "min": float(np.min(c.acceptance)),
                                        "max": float(np.max(c.acceptance))},
                "log_posterior_evaluations": self.post.n_evaluations,
                "resumed_from_step": self.resumed_from, "seed": self.seed, "chain_file": self.chain_file,
            },
            "data": {
                "rows": self.post.n_rows,
                "records": [{"file": s.file, "frequency_hz": s.frequency_hz, "rows": s.n,
                             "samples": s.full_samples, "simulated_samples": int(s.u.size), "shortened": s.proxy}
                            for s in self.post.segments],
                "input_range": list(self.post.input_range),
            },
            "start": self.start,
            "modes": self.modes_summary(),
            "at_prior_bound": self.at_prior_bound(),
            "correlation": {"names": names, "matrix": [[round(float(v), 4) for v in row] for row in corr]},
            "wall_seconds": self.wall_seconds,
            "sampling_seconds": self.sampling_seconds,
            "this_run_seconds": self.this_run_seconds,
            "notes": self.notes,
        }


BOUND_BAND = 0.01  # "at a prior bound": within this share of the prior's range from it
BOUND_SHARE = 0.05  # a nonlinear parameter with this share of its kept states at a bound is reported


def bound_shares(values: np.ndarray, lower: np.ndarray, upper: np.ndarray, band: float = BOUND_BAND) -> np.ndarray:
    """Share of the rows of ``values`` (n, d) within ``band`` x (upper - lower) of each column's lower and
    upper bound: (d, 2)."""
    width = band * (np.asarray(upper, dtype=float) - np.asarray(lower, dtype=float))
    values = np.atleast_2d(values)
    return np.column_stack([np.mean(values <= lower + width, axis=0), np.mean(values >= upper - width, axis=0)])


def _num(x):
    x = float(x)
    return x if math.isfinite(x) else None


def _add_seconds(path: Path, wall: float, sampling: float) -> dict:
    """Add a run's seconds to the chain file's ``hysbench_seconds``; the seconds stored before it."""
    with h5py.File(path, "a") as f:
        earlier = seconds_of(f.attrs, str(path))  # checked when the file was opened
        f.attrs["hysbench_seconds"] = json.dumps({"wall": earlier["wall"] + wall,
                                                  "sampling": earlier["sampling"] + sampling})
    return earlier


def _start(post, model, dataset, n_walkers, seed, moves, start_params, path, say):
    """A fresh chain's start: the optimum, the posterior's modes, the walkers in them; stored in the chain file."""
    ts = time.perf_counter()
    if start_params is None:
        say("start: identify (varpro) ...")
        fit = identify(model, dataset, method="varpro", seed=seed)
        start_params, start_method = fit.params, "varpro"
    else:
        start_method = "given"
    nl0 = np.array([float(start_params[n]) for n in post.nonlinear_names])
    nl0 = np.clip(nl0, post.priors.nonlinear_lower, post.priors.nonlinear_upper)
    sigma0, phi0 = noise_estimate(post, nl0)
    say("start: posterior modes and Laplace covariances ...")
    modes = find_modes(post, mode_search_starts(post, screen_candidates(post, nl0, sigma0, phi0, seed)))
    best = modes[0]
    rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 11]))
    p0 = walkers_in_modes(post, modes, n_walkers, rng)
    if len(modes) > 1:
        say(f"start: a {PILOT_STEPS}-step pilot measures each mode's shape for the mode jumps ...")
        p0 = pilot_shapes(post, modes, MOVES[moves](emcee), p0, seed)
    start = {"method": start_method, "params": {k: float(v) for k, v in start_params.items()},
             "noise_from_residuals": {"sigma": sigma0, "phi": phi0},
             "mode": dict(zip(post.coord_names, map(float, best["x"]))),
             "start_sd": dict(zip(post.coord_names, map(float, np.sqrt(np.diag(best["cov"]))))),
             "mode_search": best["info"],
             "modes": [{"mode": dict(zip(post.coord_names, map(float, m["x"]))),
                        "log_posterior": m["log_posterior"], "walkers": m["walkers"],
                        "covariance": [[float(v) for v in row] for row in m["cov"]],
                        **({"pilot_mean": [float(v) for v in m["pilot_mean"]],
                            "pilot_covariance": [[float(v) for v in row] for row in m["pilot_cov"]]}
                           if "pilot_cov" in m else {})} for m in modes],
             "seconds": time.perf_counter() - ts}
    store_start(path, start)
    return start, p0


def sample_posterior(model: HysteresisModel, dataset: Dataset, *, noise: str = "ar1", n_walkers: int = 16,
                     max_steps: int = 8000, min_ess: float = 1000.0, fixed_steps: bool = False,
                     burn: int | str = "auto", seed: int | None = 0, moves: str = "de",
                     chain_file: str | os.PathLike | None = None, restart: bool = False,
                     progress: bool | None = None, check_every: int = 50, start_params: Mapping | None = None,
                     discrepancy: str = "relaxation", calibrate: bool = True, log=None) -> PosteriorRun:
    """Sample the posterior of ``model``'s parameters given ``dataset``'s identification records.

    ``max_steps`` bounds the chain; unless ``fixed_steps``, sampling stops at
    the first check (every ``check_every`` steps) where the chain after
    burn-in is >= 50 tau long and every parameter has >= ``min_ess``
    effective samples. With ``chain_file`` the chain is kept in emcee's HDF5
    backend and a later call with the same settings resumes it. The start is
    ``start_params`` if given, else the ``varpro`` optimum. ``discrepancy``:
    "relaxation" (default) or "none", see ``discrepancy``. With ``calibrate``
    the predictive noise scale is set by held-out coverage
    (``discrepancy.calibrate_scale``), else it is 1.
    """
    t0 = time.perf_counter()
    say = log or (lambda msg: None)
    if moves not in MOVES:
        raise IdentificationError(f"unknown moves {moves!r}; choose one of {', '.join(MOVES)}")
    records = dataset.identification
    if not records:
        raise IdentificationError(f"dataset {dataset.name!r} has no identification records to fit")
    for name, value, lo in (("walkers", n_walkers, 2), ("steps", max_steps, 2), ("check_every", check_every, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lo:
            raise IdentificationError(f"{name} must be an integer >= {lo}, got {value!r}")
    if not (isinstance(min_ess, (int, float)) and min_ess >= 0):
        raise IdentificationError(f"min_ess must be a number >= 0, got {min_ess!r}")
    if burn != "auto" and (isinstance(burn, bool) or not isinstance(burn, (int, np.integer)) or burn < 0):
        raise IdentificationError(f"burn must be 'auto' or an integer >= 0, got {burn!r}")
    if burn != "auto" and burn >= max_steps:
        raise IdentificationError(f"burn-in {burn} leaves no step of the at most {max_steps} steps")

    post = LogPosterior(model, records, noise=noise, seed=seed, discrepancy=discrepancy, others=dataset.validation)
    if n_walkers < 2 * post.ndim or n_walkers % 2:
        raise IdentificationError(
            f"walkers must be an even number >= {2 * post.ndim} (twice the {post.ndim} sampled coordinates "
            f"{', '.join(post.coord_names)}), got {n_walkers}")
    backend, done, start = None, 0, None
    fingerprint = settings_fingerprint(post, dataset, n_walkers, seed, moves)
    path = Path(chain_file) if chain_file is not None else None
    if path is not None:
        backend, done, start = open_backend(path, fingerprint, restart, coord_names=list(post.coord_names))
    if done and start is None:
        start = {}
    p0 = None
    try:
        if not done:
            start, p0 = _start(post, model, dataset, n_walkers, seed, moves, start_params, path, say)
        else:
            post.rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 7, done]))
    except BaseException:
        if path is not None and not done:  # a start that failed leaves no chain file holding only settings
            path.unlink(missing_ok=True)
        raise

    sampler = ensemble_sampler(n_walkers, post, backend=backend,
                               moves=with_mode_jumps(MOVES[moves](emcee), post, mode_locations(post, start),
                                                     mode_covariances(post, start), jump_centres(post, start)))
    if p0 is not None:
        sampler.random_state = np.random.RandomState(0 if seed is None else int(seed)).get_state()
    else:  # resuming: the last stored state (coordinates, log posterior, draws, random state)
        p0 = sampler.get_last_sample()
    if progress is None:
        progress = sys.stderr.isatty()
    remaining = max(0, max_steps - done)
    ts = time.perf_counter()
    conv = None
    if done >= 2 and not fixed_steps:  # a resumed chain that already meets the stopping rule is only re-reported
        c = convergence(sampler.get_chain(), sampler.get_blobs(), sampler.backend.accepted, burn, min_ess,
                        sampler.get_log_prob())
        if c.converged and c.ess_met:
            conv, remaining = c, 0
    if remaining:
        bar = None
        if progress:
            bar = tqdm(total=max_steps, initial=done, desc="sampling", unit="step", file=sys.stderr,
                       dynamic_ncols=True)
        try:
            for k, _ in enumerate(sampler.sample(p0, iterations=remaining, progress=False), start=done + 1):
                if bar is not None:
                    bar.update(1)
                # a given burn-in is checked only once the chain is longer than it
                if not fixed_steps and k % check_every == 0 and k >= 2 * check_every and (burn == "auto" or k > burn):
                    c = convergence(sampler.get_chain(), sampler.get_blobs(), sampler.backend.accepted, burn,
                                    min_ess, sampler.get_log_prob())
                    if bar is not None:
                        bar.set_postfix_str(f"tau {c.tau_max:.1f}, {c.length_in_tau:.0f} tau, "
                                            f"ESS min {np.nanmin(c.ess):.0f}")
                    if c.converged and c.ess_met:
                        conv = c
                        break
        except BaseException:  # Ctrl-C or an error: the chain file keeps the steps and the time they took
            if path is not None:
                _add_seconds(path, time.perf_counter() - t0, time.perf_counter() - ts)
            raise
        finally:
            if bar is not None:
                bar.close()
            if hasattr(sampler.backend, "flush"):
                sampler.backend.flush()
    sampling_seconds = time.perf_counter() - ts
    chain = sampler.get_chain()
    draws = sampler.get_blobs()
    if draws.ndim == 2:  # a single linear parameter
        draws = draws[:, :, None]
    if conv is None or conv.n_steps != chain.shape[0]:
        conv = convergence(chain, draws, sampler.backend.accepted, burn, min_ess, sampler.get_log_prob())
    wall = time.perf_counter() - t0
    earlier = {"wall": 0.0, "sampling": 0.0}
    if path is not None:  # seconds spent on this chain file, over every run that built it
        earlier = _add_seconds(path, wall, sampling_seconds)
    run = PosteriorRun(post=post, chain=chain, draws=draws, log_prob=sampler.get_log_prob(), conv=conv,
                       start=start, wall_seconds=earlier["wall"] + wall,
                       sampling_seconds=earlier["sampling"] + sampling_seconds, this_run_seconds=wall,
                       resumed_from=done, n_walkers=n_walkers, moves=moves, seed=seed, dataset=dataset.name,
                       chain_file=None if path is None else str(path))
    if len(run.mode_locations()) > 1:
        shares = ", ".join(f"{v:.0%}" for v in run.mode_shares())
        where = "; ".join(", ".join(f"{n} {m['mode'][n]:.3g}" for n in post.nonlinear_names)
                          for m in start["modes"])
        run.notes.append(
            f"the posterior has {len(start['modes'])} separated modes ({where}); the walkers started evenly in "
            f"them, the ensemble moves drew their helper walkers from the walker's own mode, mode jumps (mapped "
            f"by each mode's mean and covariance from a {PILOT_STEPS}-step pilot run) were {JUMP_SHARE:.0%} of the "
            f"moves, and the kept states lie {shares} in each; "
            "medians and intervals span every mode; the predictive scale is calibrated in each mode at its own "
            "median state, and each predictive draw is scaled about its mode's median by its mode's scale")
    for name, b in run.at_prior_bound().items():
        run.notes.append(
            f"{name}: {b['share']:.0%} of the kept states lie within {BOUND_BAND:.0%} of the prior's range from its "
            f"{b['bound']} bound {b['value']:g}; the prior cuts the posterior off there, so that end of its interval "
            "is the bound's, not the data's")
    if calibrate:
        say("predictive scale: in-sample and leave-one-record-out coverage ...")
        states = [run.median_state(k) for k in range(max(1, len(run.mode_locations())))]
        run.mode_calibrations = [None if st is None else calibrate_scale(post, *st) for st in states]
        run.calibration = run.mode_calibrations[run.main_mode()]
    else:
        run.calibration = Calibration(0.9, constant=1.0, note="not calibrated (calibrate=False): scale 1")
    return run


