"""Lines: a sinusoid unrelated to the drive, its phase free in every record (``causes.interference``, or on top
of another cause). Its frequency: a peak of the pooled spectrum of the null's residual, refined by what it leaves
when scored as a held-out record is (``loo_rss``). It is fitted jointly with the part it sits on (``joint_line``);
on top of a clip, and when locked to the drive, on the part's residual (``on_top``)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.linalg import block_diag

from .candidates import bracketed_minimum, column_basis, prominence
from .residuals import coherent_spectrum, harmonic_phase_turn, spectral_peaks

N_PEAKS = 5  # spectral peaks each refined by a line search


def rms(values) -> float:
    return float(np.sqrt(np.mean(np.square(values))))


def row_times(screen) -> list[np.ndarray]:
    """Per record: the times of its screen rows from its start."""
    return [p.rows * p.record.dt for p in screen.parts]


def sinusoid_columns(t: np.ndarray, frequency_hz: float) -> np.ndarray:
    phase = 2.0 * np.pi * frequency_hz * t
    return np.column_stack([np.sin(phase), np.cos(phase)])


def block_columns(times: Sequence[np.ndarray], frequency_hz: float) -> np.ndarray:
    """Block-diagonal (sin, cos) columns, one pair per record (``times``: each one's rows)."""
    return block_diag(*(sinusoid_columns(t, frequency_hz) for t in times))


def best_frequency(screen, rss_of: Callable[[float], float], parts: Sequence[int] | None = None) -> float:
    """The most prominent peaks of the pooled spectrum of the null's residual on ``parts`` (default: every record),
    drive harmonics left out, each refined by a line search of ``rss_of``; the best."""
    lo, hi = screen.bounds_of(screen.extension(("interference",)), "interference_frequency")
    residuals = screen.null_residuals()
    if parts is not None:
        residuals = [residuals[m] for m in parts]
    nyquist = 0.45 / max(p.record.dt for p in screen.parts)  # below every record's Nyquist frequency
    f, amp = coherent_spectrum(residuals, lo, min(hi, nyquist), coherent=False)
    prom = prominence(amp)
    prom[drive_harmonic(screen, f, 2.0 * (f[1] - f[0]) if f.size > 1 else 0.0)] = 0.0
    best_f, best_rss = float(min(max(10.0, lo), hi)), math.inf
    step = 1.0 / max(p.record.t.size * p.record.dt for p in screen.parts)  # one cycle over the longest record
    for f0, _ in spectral_peaks(f, prom, n=N_PEAKS, min_separation_hz=max(lo, 0.05)):
        grid = [g for g in f0 + step * np.linspace(-1.0, 1.0, 11) if lo <= g <= hi]
        f1, rss = bracketed_minimum(rss_of, grid, 1e-3 * step) if grid else (f0, math.inf)
        if rss < best_rss:
            best_f, best_rss = f1, rss
    return best_f


def fold_tolerance_hz(screen) -> float:
    """How far one line's frequencies fitted on different folds may differ: the coarsest fold's resolution (one
    cycle over its longest training record)."""
    spans = [p.record.t.size * p.record.dt for p in screen.parts]
    return max(1.0 / max(s for k, s in enumerate(spans) if k != m) for m in range(len(spans)))


def frequencies_agree(screen, fold_frequencies_hz: Sequence[float]) -> bool:
    """Whether the folds' frequencies (each fitted without its held-out record) are one line's."""
    f = np.asarray(fold_frequencies_hz, dtype=float)
    return bool(f.size > 1 and np.ptp(f) <= fold_tolerance_hz(screen))


def sinusoid_fit(residual: np.ndarray, t: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Least-squares (sin, cos) coefficients of a sinusoid of this frequency in ``residual``."""
    return np.linalg.lstsq(sinusoid_columns(t, frequency_hz), residual, rcond=None)[0]


def amplitude_at(residual: np.ndarray, t: np.ndarray, frequency_hz: float) -> float:  # its phase free
    return float(math.hypot(*sinusoid_fit(residual, t, frequency_hz)))


def phase_at(residual: np.ndarray, times: np.ndarray, frequency_hz: float) -> float:
    """The phase (from the record's start) of the sinusoid fitted to a record's first ``residual.size`` rows."""
    a, b = sinusoid_fit(residual, times[:residual.size], frequency_hz)
    return float(math.atan2(b, a))


def phase_fitted(residual: np.ndarray, t: np.ndarray, frequency_hz: float, amplitude: float) -> np.ndarray:
    """The sinusoid of the given frequency and amplitude with the phase that fits ``residual`` best."""
    ab = sinusoid_fit(residual, t, frequency_hz)
    norm = math.hypot(*ab)
    return sinusoid_columns(t, frequency_hz) @ (amplitude * (ab / norm if norm > 0 else np.array([1.0, 0.0])))


def training_records(screen, m: int, train_residual: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Fold ``m``'s residual on its training rows cut into its records (all but ``m``), each with its times."""
    sizes = [p.rows.size for k, p in enumerate(screen.parts) if k != m]
    times = [t for k, t in enumerate(row_times(screen)) if k != m]
    return list(zip(np.split(train_residual, np.cumsum(sizes)[:-1]), times))


def lines_removed(screen, m: int, train_residual: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Fold ``m``'s training residual with a sinusoid of this frequency fitted in each of its records."""
    return np.concatenate([r - sinusoid_columns(t, frequency_hz) @ sinusoid_fit(r, t, frequency_hz)
                           for r, t in training_records(screen, m, train_residual)])


def fold_amplitude(screen, m: int, train_residual: np.ndarray, frequency_hz: float) -> float:
    """The amplitude fold ``m`` predicts its left-out record with: the rms of its training records' own."""
    return rms([amplitude_at(r, t, frequency_hz) for r, t in training_records(screen, m, train_residual)])


def fold_frequencies(screen, train_residuals: Sequence[np.ndarray]) -> list[float]:
    """A line's frequency on top of a primary cause per fold, chosen as it is then scored (``on_top``): by
    ``loo_rss`` on the primary's residual on the fold's training rows (``train_residuals``)."""
    n = len(screen.parts)
    out = []
    for m in range(n):
        records = training_records(screen, m, train_residuals[m])
        rss = lambda g, rec=records: loo_rss([r for r, _ in rec], [t for _, t in rec], g)  # noqa: E731
        out.append(best_frequency(screen, rss, [k for k in range(n) if k != m]))
    return out


def loo_rss(residuals: Sequence[np.ndarray], times: Sequence[np.ndarray], frequency_hz: float) -> float:
    """What a sinusoid leaves of the residuals when each record takes the others' amplitude (rms) and fits only
    its phase, as a held-out record does (with one record, amplitude and phase its own)."""
    S = [sinusoid_columns(t, frequency_hz) for t in times]
    ab = [np.linalg.lstsq(s, r, rcond=None)[0] for s, r in zip(S, residuals)]  # each record's fit, used twice
    amp = [float(math.hypot(*c)) for c in ab]
    total = 0.0
    for k, r in enumerate(residuals):
        rest = [a for j, a in enumerate(amp) if j != k] or [amp[k]]
        direction = ab[k] / amp[k] if amp[k] > 0 else np.array([1.0, 0.0])  # as ``phase_fitted``
        left = r - S[k] @ (rms(rest) * direction)
        total += float(left @ left)
    return total


def on_top(screen, folds, e_primary: np.ndarray, train_residuals: Sequence[np.ndarray],
           frequency_hz: float | Sequence[float]) -> np.ndarray:
    """Out-of-fold residuals ``e_primary`` of a primary cause less a sinusoid on each scored record, its amplitude
    from the other records (``fold_amplitude``), its phase fitted; one frequency, or one per fold."""
    f = np.broadcast_to(np.asarray(frequency_hz, dtype=float), (len(screen.parts),))
    times = row_times(screen)
    e = e_primary.copy()
    for m in range(len(screen.parts)):
        e[folds.tail(m)] = 0.0  # not held-out targets (``selection.Folds``)
        if folds.is_scored(m):
            rows = folds.head(m)
            a = fold_amplitude(screen, m, train_residuals[m], f[m])
            e[rows] = e_primary[rows] - phase_fitted(e_primary[rows], times[m][:rows.stop - rows.start], f[m], a)
    return e


def on_top_estimates(screen, folds, e_primary: np.ndarray, train_residuals: Sequence[np.ndarray],
                     frequencies_hz: Sequence[float]) -> dict:
    """What a sinusoid scored by ``on_top`` with one frequency per fold stands for (``line_estimates``)."""
    times = row_times(screen)
    phases = [phase_at(e_primary[folds.head(m)], times[m], f) for m, f in enumerate(frequencies_hz)
              if folds.is_scored(m)]  # no held-out residual elsewhere
    amps = [fold_amplitude(screen, m, r, f) for m, (r, f) in enumerate(zip(train_residuals, frequencies_hz))]
    return line_estimates(frequencies_hz, amps, phases)


def line_estimates(frequencies_hz: Sequence[float], amplitudes: Sequence[float], phases: list) -> dict:
    """What a line scored per fold stands for (for ``Cause.limit``)."""
    return {"frequency_hz": float(np.mean(frequencies_hz)), "amplitude": rms(amplitudes),
            "phase_rad_per_record": list(phases), "fold_frequencies_hz": [float(f) for f in frequencies_hz]}


class JointLine:
    """A part (its stacked design ``A``) fitted jointly with a line, one (sin, cos) pair per record of ``records``:
    fitted on the part's residual alone, a line near a drive harmonic would be partly taken up by the part."""

    def __init__(self, screen, A: np.ndarray, records: Sequence[int]):
        starts = np.cumsum([0] + [p.rows.size for p in screen.parts])
        rows = np.concatenate([np.arange(starts[k], starts[k + 1]) for k in records])
        self.A, self.y = A[rows], screen.y[rows]
        self.Q = column_basis(self.A)
        self.r0 = self.y - self.Q @ (self.Q.T @ self.y)
        times = row_times(screen)
        self.times = [times[k] for k in records]
        self.cuts = np.cumsum([t.size for t in self.times])[:-1]

    def fit(self, frequency_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """(the line on these rows, the residual of the part alone: the line left in)."""
        S = block_columns(self.times, frequency_hz)
        P = self.Q @ (self.Q.T @ S)
        c = np.linalg.lstsq(S - P, self.r0, rcond=None)[0]
        return S @ c, self.r0 + P @ c

    def parts(self, frequency_hz: float) -> list[np.ndarray]:
        """The part's residual with the line left in, one array per record."""
        return np.split(self.fit(frequency_hz)[1], self.cuts)

    def loo_rss(self, frequency_hz: float) -> float:
        return loo_rss(self.parts(frequency_hz), self.times, frequency_hz)

    def amplitude(self, frequency_hz: float) -> float:
        """The line's amplitude: rms over the records of each one's (its own phase)."""
        return rms([amplitude_at(r, t, frequency_hz) for r, t in zip(self.parts(frequency_hz), self.times)])


@dataclass
class FoldLines:
    """``joint_line``'s result: ``errors`` with the line removed, ``part_errors`` without, ``train_residuals`` per fold
    the joint fit's residual on its training rows, ``phases`` each scored record's from its start."""

    errors: np.ndarray
    part_errors: np.ndarray
    frequencies_hz: list
    amplitudes: list
    train_residuals: list
    phases: list

    def estimates(self) -> dict:
        return line_estimates(self.frequencies_hz, self.amplitudes, self.phases)


def joint_line(screen, folds, design: Callable[[int], np.ndarray],
               frequencies_hz: Sequence[float] | None = None) -> FoldLines:
    """A part (``design(m)``: fold m's stacked design, all rows) and a line fitted jointly on each fold's training
    records, its frequency chosen there unless given; the left-out record is predicted by the part fitted alone
    and the line with the training records' amplitude, its phase fitted."""
    n = len(screen.parts)
    times = row_times(screen)
    e, part_e = np.zeros(screen.n), np.zeros(screen.n)
    freqs, amps, train, phases = [], [], [], []
    for m in range(n):
        others = [k for k in range(n) if k != m]
        A = design(m)
        line = JointLine(screen, A, others)
        f = float(frequencies_hz[m]) if frequencies_hz is not None else best_frequency(screen, line.loo_rss, others)
        fitted, with_line = line.fit(f)
        theta, _ = screen.solve(line.A, line.y)  # the part alone: a disturbance does not change what is driven
        test = folds.test(m)
        part_e[test] = screen.y[test] - A[test] @ theta
        part_e[folds.tail(m)] = 0.0
        a = line.amplitude(f)
        e[test] = part_e[test]
        if folds.is_scored(m):
            rows = folds.head(m)
            e[rows] = part_e[rows] - phase_fitted(part_e[rows], times[m][:rows.stop - rows.start], f, a)
            phases.append(phase_at(part_e[rows], times[m], f))
        freqs.append(f)
        amps.append(a)
        train.append(with_line - fitted)
    return FoldLines(e, part_e, freqs, amps, train, phases)


def drive_locked(screen, estimates: Mapping) -> bool:
    """A sinusoid at a harmonic of every record's drive (within half a cycle over the longest record), its phases
    within ``locked_phase``, not turning from period to period (``locked_turn``, ``locked_turn_z``): a misfit."""
    phases = estimates.get("phase_rad_per_record") or []
    longest = max(p.record.t.size * p.record.dt for p in screen.parts)
    if len(phases) < 2 or not drive_harmonic(screen, np.array([estimates["frequency_hz"]]), 0.5 / longest)[0]:
        return False
    spread = max(abs(math.remainder(a - b, 2 * math.pi)) for i, a in enumerate(phases) for b in phases[i + 1:])
    pol = screen.policy
    if spread >= pol.locked_phase:
        return False
    turn = harmonic_phase_turn(screen.null_residuals(), estimates["frequency_hz"])
    return turn is None or not (abs(turn[0]) > pol.locked_turn and abs(turn[0]) > pol.locked_turn_z * turn[1])


def drive_harmonic(screen, f: np.ndarray, tolerance_hz: float) -> np.ndarray:
    """Whether each frequency is a harmonic of every identification record's drive (within tolerance)."""
    out = np.ones(f.shape, dtype=bool)
    for p in screen.parts:
        fd = p.record.frequency_hz
        if not fd:
            return np.zeros(f.shape, dtype=bool)
        k = np.maximum(np.round(f / fd), 1.0)
        out &= np.abs(f - k * fd) <= tolerance_hz
    return out
