"""The posterior predictive: bands on records' scored windows, their coverage, and synthetic data
with AR(1) noise for calibration checks."""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np
from scipy.signal import lfilter

from hysbench.data.dataset import Dataset, Record
from hysbench.data.protocol import simulated_dataset
from hysbench.models.base import HysteresisModel

from .modes import nearest_mode
from .run import PosteriorRun
from .target import build_segments

LEVELS = (0.5, 0.9)


def ar1_noise(n: int, sigma: np.ndarray, phi: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Stationary AR(1) noise paths, one per (sigma, phi): (len(sigma), n)."""
    sigma, phi = np.atleast_1d(sigma), np.atleast_1d(phi)
    out = np.empty((sigma.size, n))
    for k in range(sigma.size):
        eps = rng.standard_normal(n) * sigma[k]
        eps[0] /= math.sqrt(1.0 - phi[k] ** 2)
        out[k] = lfilter([1.0], [1.0, -phi[k]], eps)
    return out


def scale_about_mode_medians(Y: np.ndarray, mode: np.ndarray, scales) -> np.ndarray:
    """Draws (n, T) with each draw's deviation from its own mode's per-sample median multiplied by that
    mode's scale: median_k + scales[k] (Y - median_k) for the rows in mode k."""
    out = np.empty_like(Y)
    for k in np.unique(mode):
        rows = mode == k
        centre = np.median(Y[rows], axis=0)
        out[rows] = centre + scales[int(k)] * (Y[rows] - centre)
    return out


def needed_multipliers(y: np.ndarray, Y: np.ndarray, mode: np.ndarray, scales, level: float = 0.9,
                       bounds: tuple[float, float] = (1e-2, 1e2), iterations: int = 16) -> np.ndarray:
    """Per sample: the smallest common multiplier m of the modes' scales at which y lies inside the
    ``level`` band of ``scale_about_mode_medians(Y, mode, m * scales)`` (inf: not even at the upper bound).

    One mode: the band is the median plus m times the scaled deviations' quantiles, so m follows in
    closed form. Several modes: bisection in log m, all samples at once.
    """
    q = [(1 - level) / 2, 1 - (1 - level) / 2]
    scales = np.asarray(scales, float)
    lo_m, hi_m = bounds
    centres = scale_about_mode_medians(Y, mode, np.zeros_like(scales))  # each row: its mode's median
    dev = scale_about_mode_medians(Y, mode, scales) - centres  # the band's draws at m: centres + m dev
    if np.unique(mode).size == 1:
        qlo, qhi = np.quantile(dev, q, axis=0)
        d = y - centres[0]
        with np.errstate(divide="ignore", invalid="ignore"):
            m = np.where(d > 0, d / qhi, np.where(d < 0, d / qlo, 0.0))
        m = np.where(np.isfinite(m) & (m >= 0), m, np.inf)
        return np.where(m > hi_m, np.inf, m)

    def inside(m):
        lo, hi = np.quantile(centres + m * dev, q, axis=0)
        return (y >= lo) & (y <= hi)

    a, b = np.full(y.shape, math.log(lo_m)), np.full(y.shape, math.log(hi_m))
    never = ~inside(np.full(y.shape, hi_m))
    already = inside(np.full(y.shape, lo_m))
    for _ in range(iterations):
        mid = 0.5 * (a + b)
        ok = inside(np.exp(mid))
        b, a = np.where(ok, mid, b), np.where(ok, a, mid)
    m = np.exp(b)
    m[already] = lo_m
    m[never] = np.inf
    return m


def multiplier_for_coverage(m: np.ndarray, targets=(0.8, 0.9, 0.97)) -> dict:
    """The smallest multiplier at which the share of samples with needed multiplier <= it reaches each
    target ({"80": .., "90": .., "97": ..}; None where it is not reached within the bounds)."""
    out = {}
    for t in targets:
        v = float(np.quantile(m, t, method="inverted_cdf"))
        out[f"{int(round(t * 100))}"] = v if math.isfinite(v) else None
    return out


def _inside(y, lo, hi) -> float:
    return float(np.mean((y >= lo) & (y <= hi)))


def predictive(run: PosteriorRun, records: Sequence[Record], n_draws: int = 200, level: float = 0.9,
               seed: int | None = 0) -> list[dict]:
    """Posterior predictive bands on records' scored windows and the share of measured samples inside.

    For ``n_draws`` kept states (evenly spaced) the model output (with the
    discrepancy term) is computed and an AR(1) (or iid) noise path with that
    state's sigma, phi is added. Each such draw's deviation from the per-sample
    median is then multiplied by the held-out calibration's scale at the
    record's frequency (``run.predictive_scale``, see ``discrepancy``). With
    separated posterior modes, each draw's deviation is taken from the median
    of its own mode's draws and scaled by that mode's scale, and
    ``predictive_scale`` is the main mode's (``predictive_scale_per_mode``
    lists every mode's).
    ``observation`` bands include the noise (where a new measurement should
    fall), ``model`` bands only the parameter uncertainty (unscaled).
    ``coverage`` holds the 50 % and 90 % bands' coverage and mean width;
    ``unscaled`` the same with scale 1. ``multiplier_for_coverage``: the factor on the used
    scale(s) at which the ``level`` band would cover 80 / 90 / 97 % of this record's samples
    (1: the used scale is what this record needed). Draws whose model output is not finite
    are left out and counted in ``nonfinite_draws``. ``inside_fitted_range``:
    whether the record's frequency lies within the identification records'
    range (False: extrapolated, where the bands are not calibrated; None:
    unknown or one frequency only).
    """
    post = run.post
    rng = np.random.default_rng(np.random.SeedSequence([0 if seed is None else int(seed), 13]))
    b = run.conv.burn
    ch = run.chain[b:].reshape(-1, run.chain.shape[-1])
    dr = run.draws[b:].reshape(-1, run.draws.shape[-1])
    pick = np.linspace(0, ch.shape[0] - 1, min(n_draws, ch.shape[0])).round().astype(int)
    nl, sigma, phi = post.split(ch[pick])
    modes = run.mode_locations()
    n_modes = max(1, len(modes))
    mode = nearest_mode(post, ch[pick], modes)
    lin = dr[pick]
    lo_q, hi_q = (1 - level) / 2, 1 - (1 - level) / 2
    check = nl[:1] if len(post.nonlinear_names) else np.zeros((1, 0))
    segs = build_segments(post.model, records, post.input_range, check, taus=post.taus)
    out = []
    for s in segs:
        Y = post.window_outputs(s, nl, lin)
        finite = np.isfinite(Y).all(axis=1)
        noise = ar1_noise(s.n, sigma, phi, rng)
        Y, noise, in_mode = Y[finite], noise[finite], mode[finite]
        y = s.y
        scales = [run.predictive_scale(s.frequency_hz, k) for k in range(n_modes)]
        row = {"file": s.file, "frequency_hz": s.frequency_hz, "rows": s.n, "draws": int(finite.sum()),
               "nonfinite_draws": int((~finite).sum()), "predictive_scale": run.predictive_scale(s.frequency_hz),
               "inside_fitted_range": run.inside_fitted_range(s.frequency_hz)}
        if n_modes > 1:
            row["predictive_scale_per_mode"] = scales
        if not finite.any():
            row.update(coverage=None, unscaled=None, rms_error_of_median=None)
            out.append(row)
            continue
        Yraw = Y + noise
        Yobs = scale_about_mode_medians(Yraw, in_mode, scales)
        cov, raw = {}, {}
        for lev in LEVELS:
            q = [(1 - lev) / 2, 1 - (1 - lev) / 2]
            olo, ohi = np.quantile(Yobs, q, axis=0)
            rlo, rhi = np.quantile(Yraw, q, axis=0)
            key = f"{int(round(lev * 100))}"
            cov[key], cov[f"width_{key}"] = _inside(y, olo, ohi), float(np.mean(ohi - olo))
            raw[key], raw[f"width_{key}"] = _inside(y, rlo, rhi), float(np.mean(rhi - rlo))
        need = multiplier_for_coverage(needed_multipliers(y, Yraw, in_mode, scales, level))
        mlo, mhi = np.quantile(Y, [lo_q, hi_q], axis=0)
        olo, ohi = np.quantile(Yobs, [lo_q, hi_q], axis=0)
        row.update({
            "coverage": cov, "unscaled": raw, "multiplier_for_coverage": need,
            "fraction_inside_observation_band": _inside(y, olo, ohi),
            "fraction_inside_model_band": _inside(y, mlo, mhi),
            "mean_observation_band_width": float(np.mean(ohi - olo)),
            "mean_model_band_width": float(np.mean(mhi - mlo)),
            "rms_error_of_median": float(np.sqrt(np.mean((np.median(Y, axis=0) - y) ** 2))),
            "_t": (np.arange(s.n) * s.dt), "_y": y, "_median": np.median(Y, axis=0),
            "_obs": (olo, ohi), "_model": (mlo, mhi),
        })
        out.append(row)
    return out


def predictive_coverage(rows: Sequence[dict]) -> dict:
    """record -> {"50": .., "90": .., "width_50": .., "width_90": ..} (None where no draw was finite)."""
    return {r["file"]: r["coverage"] for r in rows}


def simulated_ar1_dataset(model: HysteresisModel, params: Mapping[str, float], *, sigma: float, phi: float,
                          seed: int = 0, **protocol) -> Dataset:
    """The paper's protocol simulated from ``model`` with stationary AR(1) noise added to every record
    (innovation sd ``sigma``, coefficient ``phi`` per sample); ``protocol`` goes to
    ``data.protocol.simulated_dataset`` (n_periods, dt, frequencies, name)."""
    ds = simulated_dataset(model, params, noise_sd=0.0, **protocol)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), 17]))
    for r in ds.records:
        r.y = r.y + ar1_noise(r.y.size, np.array([sigma]), np.array([phi]), rng)[0]
    ds.description = (f"{ds.description}; stationary AR(1) noise per record, innovation sd {sigma:g}, "
                      f"phi {phi:g} per sample, seed {seed}")
    return ds
