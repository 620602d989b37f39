"""Residuals r = y_measured - y_model of a fitted model over whole records, simulated from the first sample (a
drift or a start-up transient shows only outside the scored window), and what they look like: the noise level,
whiteness (Ljung-Box), the spectrum, the repetition from period to period, the pooled spectrum of several records.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy import stats
from scipy.ndimage import median_filter
from scipy.signal import zoom_fft

from hysbench.data.metrics import e_m, e_rms
from hysbench.data.dataset import Record
from hysbench.data.protocol import period_samples

LAGS = 20
FLOOR_HALF_WIDTH = 15  # bins each side of the running median (fewer at low frequency: k // 2, at least 2)
MAX_SPECTRUM_POINTS = 1 << 21


@dataclass
class RecordResidual:
    """A record, the model's output over all of it, and the residual."""
    record: Record
    prediction: np.ndarray

    @property
    def residual(self) -> np.ndarray:
        return self.record.y - self.prediction

    @property
    def file(self) -> str:
        return self.record.file

    def scores(self) -> dict:
        """e_m / e_rms (percent of the measured peak-to-peak) on the scored window and on the whole record."""
        r = self.record
        w = r.scored
        return {"e_m": e_m(self.prediction[w], r.y[w]), "e_rms": e_rms(self.prediction[w], r.y[w]),
                "e_m_whole": e_m(self.prediction, r.y), "e_rms_whole": e_rms(self.prediction, r.y)}


def noise_sd(r: np.ndarray) -> float:
    """Measurement-noise sd estimated from first differences (robust: MAD)."""
    d = np.diff(np.asarray(r, dtype=float))
    if d.size < 2:
        return float("nan")
    return float(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0))


def autocorrelation(r: np.ndarray, lags: int = LAGS) -> np.ndarray:
    """Sample autocorrelation at lags 1..lags (mean removed)."""
    x = np.asarray(r, dtype=float) - np.mean(r)
    den = float(x @ x)
    if den <= 0:
        return np.zeros(lags)
    return np.array([float(x[:-k] @ x[k:]) / den for k in range(1, lags + 1)])


def ljung_box(r: np.ndarray, lags: int = LAGS) -> tuple[float, float]:
    """(Q, p-value) of the Ljung-Box test of whiteness."""
    n = r.size
    if n <= lags + 1:
        return float("nan"), float("nan")
    rho = autocorrelation(r, lags)
    q = float(n * (n + 2) * np.sum(rho**2 / (n - np.arange(1, lags + 1))))
    return q, float(stats.chi2.sf(q, lags))


def periodogram(r: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """One-sided amplitude spectrum (output units) of the mean-removed residual: (f, |R| * 2 / n)."""
    x = np.asarray(r, dtype=float) - np.mean(r)
    spec = np.fft.rfft(x * np.hanning(x.size))
    amp = 2.0 * np.abs(spec) / np.sum(np.hanning(x.size))
    return np.fft.rfftfreq(x.size, dt), amp


def noise_floor(r: np.ndarray) -> np.ndarray:
    """The residual's continuous spectrum on the rfft bins, in periodogram units (|R_k|^2 / n, mean removed): a running
    median over +-min(15, k // 2) bins (at least 2), divided by ln 2 (the median of an exponential), so a few lines --
    misfit locked to the drive -- do not raise it; the window is truncated at the top, and bin 0 takes bin 1's value."""
    x = np.asarray(r, dtype=float) - np.mean(r)
    p = np.abs(np.fft.rfft(x)) ** 2 / max(x.size, 1)
    if p.size < 3:
        return np.full(p.size, float(x @ x) / max(x.size, 1))
    p[0] = p[1]
    floor = np.empty_like(p)
    if p.size > 2 * FLOOR_HALF_WIDTH + 1:  # the full window: +-FLOOR_HALF_WIDTH
        floor[1:] = median_filter(p[1:], size=2 * FLOOR_HALF_WIDTH + 1, mode="nearest")
    edges = sorted({*range(min(2 * FLOOR_HALF_WIDTH, p.size)), *range(max(0, p.size - FLOOR_HALF_WIDTH), p.size)})
    for k in edges:  # narrower at low frequency, truncated at the top
        h = min(FLOOR_HALF_WIDTH, max(2, k // 2))
        floor[k] = np.median(p[max(1, k - h):k + h + 1])
    return floor / math.log(2.0)


def gain_z(pairs: list[tuple[np.ndarray, np.ndarray]]) -> float:
    """One-sided z that going from residual r_b to r_a (pairs over records) lowers the sum of squares by more than noise
    would: D = sum(r_b^2 - r_a^2) = sum(2 d r_b - d^2), d = r_b - r_a. If d is unrelated to a record's noise e, sum(d e)
    has variance sum_k |D_k|^2 S_k / n (S: ``noise_floor`` of r_a, correlated noise included); z = D / (2 sd)."""
    gained = var = 0.0
    for r_b, r_a in pairs:
        d = r_b - r_a
        gained += float(r_b @ r_b - r_a @ r_a)
        spec = np.abs(np.fft.rfft(d)) ** 2
        w = np.full(spec.size, 2.0)
        w[0] = 1.0
        if d.size % 2 == 0:
            w[-1] = 1.0
        var += float(np.sum(w * spec * noise_floor(r_a))) / d.size
    if var <= 0:
        return math.copysign(math.inf, gained) if gained else 0.0
    return gained / (2.0 * math.sqrt(var))


def coherent_spectrum(residuals: list[RecordResidual], f_min: float, f_max: float, pad: int = 4,
                      coherent: bool = True):
    """Pooled coherent amplitude spectrum: (f, 2 |sum_m R_m(f)| / sum_m n_m) for f in [f_min, f_max], each
    record's DFT R_m in its own time, zero-padded to ``pad`` times the longest record; with ``coherent=False``
    the powers add: 2 sqrt(sum_m |R_m|^2 / sum_m n_m^2)."""
    dts = np.array([rr.record.dt for rr in residuals])
    if dts.max() - dts.min() > 1e-9 * dts.max():  # sample times that differ: each DFT on one grid (chirp z)
        f_lo, f_hi = max(f_min, 0.0), min(f_max, 0.5 / dts.max())
        if not f_hi > f_lo:
            return np.empty(0), np.empty(0)
        df = 1.0 / (pad * max(rr.record.t.size * rr.record.dt for rr in residuals))
        m = int(math.floor((f_hi - f_lo) / df)) + 1
        if m > MAX_SPECTRUM_POINTS:
            m = MAX_SPECTRUM_POINTS
            df = (f_hi - f_lo) / (m - 1)
        f, keep = f_lo + df * np.arange(m), slice(None)

        def dft(x, dt):
            return zoom_fft(x, [f_lo, f_lo + m * df], m=m, fs=1.0 / dt)
    else:
        n_fft = 1 << int(math.ceil(math.log2(pad * max(rr.record.t.size for rr in residuals))))
        f = np.fft.rfftfreq(n_fft, float(np.median(dts)))
        keep = (f >= f_min) & (f <= f_max)

        def dft(x, dt):
            return np.fft.rfft(x, n_fft)
    total, n_total, n2 = 0.0, 0, 0
    for rr in residuals:
        x = rr.residual - np.mean(rr.residual)
        spec = dft(x, rr.record.dt)
        total = total + (spec if coherent else np.abs(spec) ** 2)
        n_total += x.size
        n2 += x.size**2
    total = total[keep]
    return f[keep], 2.0 * np.abs(total) / n_total if coherent else 2.0 * np.sqrt(total / n2)


def spectral_peaks(f: np.ndarray, amp: np.ndarray, n: int = 3, min_separation_hz: float = 0.5) -> list[tuple[float, float]]:
    """The n largest local maxima of a spectrum, at least ``min_separation_hz`` apart: [(f, amplitude)]."""
    if f.size < 3:
        return []
    is_peak = np.r_[False, (amp[1:-1] >= amp[:-2]) & (amp[1:-1] >= amp[2:]), False]
    idx = np.flatnonzero(is_peak)
    idx = idx[np.argsort(-amp[idx])]
    out: list[tuple[float, float]] = []
    for i in idx:
        if all(abs(f[i] - g) >= min_separation_hz for g, _ in out):
            out.append((float(f[i]), float(amp[i])))
        if len(out) == n:
            break
    return out


@dataclass
class ResidualSummary:
    """Per-record statistics of a residual."""
    file: str
    role: str
    frequency_hz: float | None
    noise_sd: float
    rms: float
    rms_window: float
    ljung_box_q: float
    ljung_box_p: float
    lag1_autocorrelation: float
    scores: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        return dict(self.__dict__)


def summarise(residuals: list[RecordResidual]) -> list[ResidualSummary]:
    out = []
    for rr in residuals:
        r = rr.residual
        q, p = ljung_box(r)
        w = r[rr.record.scored]
        out.append(ResidualSummary(
            file=rr.file, role=rr.record.role, frequency_hz=rr.record.frequency_hz, noise_sd=noise_sd(r),
            rms=float(np.sqrt(np.mean(r**2))), rms_window=float(np.sqrt(np.mean(w**2))), ljung_box_q=q,
            ljung_box_p=p, lag1_autocorrelation=float(autocorrelation(r, 1)[0]), scores=rr.scores()))
    return out


def phase_of(record: Record) -> np.ndarray | None:
    """Phase within the drive period (0..1) of every sample, or None for a non-periodic record."""
    if not record.frequency_hz:
        return None
    return np.mod((record.t - record.t[0]) * record.frequency_hz, 1.0)


def whole_periods(record: Record) -> tuple[int, int]:
    """Samples per drive period and the number of whole periods in the record ((0, 0) if not periodic)."""
    if not record.frequency_hz:
        return 0, 0
    n_p = period_samples(record.frequency_hz, record.dt)
    return n_p, (record.t.size // n_p if n_p > 0 else 0)


def periodic_structure(residuals: list[RecordResidual], n_bins: int = 100) -> dict:
    """Whether a residual repeats from one drive period to the next: per record of at least two whole periods (records
    of one period at the same frequency and length taken together), the residual in ``n_bins`` phase bins per period, X
    (P x bins); F = P mean_p(X)^2 / var_p(X) summed over bins and records: about 1 for noise independent from period to
    period, large for a misfit the drive repeats. {"F" (nan without such records), "records"}."""
    num = den = 0.0
    used = []
    single: dict[tuple, list[tuple[str, np.ndarray]]] = {}
    blocks = []
    for rr in residuals:
        r = rr.record
        n_p, P = whole_periods(r)
        if P >= 2:
            blocks.append(([r.file], rr.residual[:P * n_p].reshape(P, n_p)))
        elif P == 1:
            single.setdefault((float(r.frequency_hz), n_p), []).append((r.file, rr.residual[:n_p]))
    blocks += [([f for f, _ in g], np.stack([x for _, x in g])) for g in single.values() if len(g) >= 2]
    for files, X in blocks:
        P, n_p = X.shape
        nb = min(n_bins, n_p)
        X = X[:, : (n_p // nb) * nb].reshape(P, nb, -1).mean(axis=2)
        X = X - X.mean()
        mean = X.mean(axis=0)
        num += P * float(mean @ mean)
        den += float(np.sum((X - mean) ** 2)) / (P - 1)
        used += files
    return {"F": num / den if den > 0 else (math.inf if num > 0 else math.nan), "records": used}


def harmonic_phase_turn(residuals: list[RecordResidual], frequency_hz: float) -> tuple[float, float] | None:
    """How far a sinusoid near a drive harmonic turns in phase from one drive period to the next: (turn, its
    standard error) in rad per period, from the residual's complex amplitude c_j at the harmonic in each whole
    period j (turn: the angle of sum c_(j+1) conj(c_j); error: the rms of c_(j+1) - c_j e^(i turn) over the rms
    amplitude and sqrt(pairs)). A misfit locked to the drive stays put. None with fewer than two pairs."""
    products = []
    for rr in residuals:
        r = rr.record
        n_p, P = whole_periods(r)
        if P < 2:
            continue
        harmonic = max(round(frequency_hz / r.frequency_hz), 1) * r.frequency_hz
        X = rr.residual[:P * n_p].reshape(P, n_p)
        X = X - X.mean(axis=1, keepdims=True)
        c = 2.0 * X @ np.exp(-2j * np.pi * harmonic * np.arange(n_p) * r.dt) / n_p
        products.append(np.column_stack([c[:-1], c[1:]]))
    if not products:
        return None
    pairs = np.concatenate(products)
    if len(pairs) < 2:
        return None
    turn = float(np.angle(np.sum(pairs[:, 1] * np.conj(pairs[:, 0]))))
    misfit = np.sqrt(np.mean(np.abs(pairs[:, 1] - pairs[:, 0] * np.exp(1j * turn)) ** 2))
    amplitude = np.sqrt(np.mean(np.abs(pairs) ** 2))
    se = float(misfit / amplitude / math.sqrt(len(pairs))) if amplitude > 0 else math.inf
    return turn, se
