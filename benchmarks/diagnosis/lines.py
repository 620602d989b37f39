"""Lines: a sinusoid unrelated to the drive, with its own phase in every record, fitted and scored
(the interference cause, ``causes.interference``, and every line on top of another cause).

A disturbance (mains pickup, a building's vibration) is not driven by the
input, so its phase relative to a record's start is arbitrary: the fit has
one frequency and one (sin, cos) pair per record. Candidate frequencies are
the most prominent peaks of the pooled incoherent spectrum of the null's
residual (records' powers added), harmonics common to every drive left out,
each refined by a line search. The line is estimated jointly with the part it
sits on (the base, or a named cause; ``JointLine``): fitted on the part's
residual alone, a line close to a harmonic of the drive would be partly taken up
by the part first, its amplitude low and its frequency pushed off the
harmonic. On a held-out record the frequency and the
amplitude come from the other records, so estimated, and only the phase is
fitted there, on top of the part's own held-out prediction (``joint_line``):
a disturbance does not change what the input drives, so the part is fitted on
the other records alone on both sides of the comparison, and a line is judged
only by what it removes from each held-out record (solved together with the
line, the part's prediction of a record it predicts poorly can move by more
than the line removes). Scored with its own parameters refitted per
fold, the frequency too is searched afresh on the other records, so a held-out
record takes no part in choosing the frequency it is scored at. A fold chooses
its frequency the way it is scored: each of its records predicted with the
amplitude of the others, only the phase its own (``loo_rss``), so a misfit at
a harmonic of some drives, strong in one record and weak in another, loses to
a line of one amplitude. So does the fit on every identification record,
whose frequency is the one reported. The validation records confirm it the
same way. On top of a clip (not linear) the line is fitted on its residual
(``fold_frequencies``, ``on_top``), and so is a line locked to the drive (no
disturbance: the base's own misfit at a harmonic, shown as a rival of a
partial cause, ``selection.why_not_specific``): fitted jointly, the base takes
up part of its misfit there, which the base fitted alone, as it predicts a
held-out record, does not, and the line would understate it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np
from scipy.optimize import minimize_scalar

from .candidates import column_basis, prominence
from .residuals import coherent_spectrum, harmonic_phase_turn, spectral_peaks


def sinusoid_columns(t: np.ndarray, frequency_hz: float) -> np.ndarray:
    phase = 2.0 * np.pi * frequency_hz * t
    return np.column_stack([np.sin(phase), np.cos(phase)])


def block_columns(screen, frequency_hz: float, parts: Sequence[int] | None = None) -> np.ndarray:
    """(rows, 2 M) block-diagonal sin/cos columns on the screen's rows, one pair per record."""
    parts = range(len(screen.parts)) if parts is None else parts
    n = [screen.parts[m].rows.size for m in range(len(screen.parts))]
    starts = np.cumsum([0] + n)
    E = np.zeros((starts[-1], 2 * len(parts)))
    for j, m in enumerate(parts):
        p = screen.parts[m]
        E[starts[m]:starts[m + 1], 2 * j:2 * j + 2] = sinusoid_columns(p.rows * p.record.dt, frequency_hz)
    return E


def _search(rss_of, f0: float, step: float, lo: float, hi: float) -> tuple[float, float]:
    grid = [g for g in f0 + step * np.linspace(-1.0, 1.0, 11) if lo <= g <= hi]
    if not grid:
        return f0, math.inf
    vals = [rss_of(g) for g in grid]
    i = int(np.argmin(vals))
    a, b = grid[max(i - 1, 0)], grid[min(i + 1, len(grid) - 1)]
    best = (float(grid[i]), float(vals[i]))
    if b > a:
        res = minimize_scalar(rss_of, bounds=(a, b), method="bounded", options={"xatol": 1e-3 * step})
        if res.fun < best[1]:
            best = (float(res.x), float(res.fun))
    return best


def candidate_frequencies(screen, n_peaks: int = 5, parts: Sequence[int] | None = None) -> list[float]:
    """The most prominent peaks of the pooled spectrum of the null's residual on ``parts`` (default: every
    identification record), drive harmonics left out."""
    model = screen.extension(("interference",))
    lo, hi = screen.bounds_of(model, "interference_frequency")
    hi = min(hi, 0.45 / max(p.record.dt for p in screen.parts))  # below every record's Nyquist frequency
    residuals = screen.null_residuals()
    if parts is not None:
        residuals = [residuals[m] for m in parts]
    f, amp = coherent_spectrum(residuals, lo, hi, coherent=False)
    prom = prominence(amp)
    prom[drive_harmonic(screen, f, 2.0 * (f[1] - f[0]) if f.size > 1 else 0.0)] = 0.0
    return [f0 for f0, _ in spectral_peaks(f, prom, n=n_peaks, min_separation_hz=max(lo, 0.05))]


def resolution_hz(screen, parts: Sequence[int] | None = None) -> float:
    """The spectral resolution of the longest of ``parts`` (default: every identification record): one cycle
    over its duration."""
    parts = range(len(screen.parts)) if parts is None else parts
    return 1.0 / max(screen.parts[m].record.t.size * screen.parts[m].record.dt for m in parts)


def best_frequency(screen, rss_of: Callable[[float], float], n_peaks: int = 5,
                   parts: Sequence[int] | None = None) -> float:
    """The spectral peaks of ``parts`` (``candidate_frequencies``), each refined by a line search of
    ``rss_of``; the best."""
    lo, hi = screen.bounds_of(screen.extension(("interference",)), "interference_frequency")
    best_f, best_rss = float(min(max(10.0, lo), hi)), math.inf
    for f0 in candidate_frequencies(screen, n_peaks, parts):
        f1, rss = _search(rss_of, f0, resolution_hz(screen), lo, hi)
        if rss < best_rss:
            best_f, best_rss = f1, rss
    return best_f


def fold_tolerance_hz(screen) -> float:
    """How far the frequencies of one line fitted on different folds may differ: the coarsest fold's spectral
    resolution (one cycle over its longest training record)."""
    n = len(screen.parts)
    return max(resolution_hz(screen, [k for k in range(n) if k != m]) for m in range(n))


def frequencies_agree(screen, fold_frequencies_hz: Sequence[float]) -> bool:
    """Whether the folds' frequencies (each fitted without its held-out record) are one line's."""
    f = np.asarray(fold_frequencies_hz, dtype=float)
    return bool(f.size > 1 and np.ptp(f) <= fold_tolerance_hz(screen))


def phase_fitted(residual: np.ndarray, t: np.ndarray, frequency_hz: float, amplitude: float) -> np.ndarray:
    """The sinusoid of the given frequency and amplitude with the phase that fits ``residual`` best."""
    S = sinusoid_columns(t, frequency_hz)
    ab = np.linalg.lstsq(S, residual, rcond=None)[0]
    norm = math.hypot(*ab)
    direction = ab / norm if norm > 0 else np.array([1.0, 0.0])
    return S @ (amplitude * direction)


def sinusoid_fit(residual: np.ndarray, t: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Least-squares (sin, cos) coefficients of a sinusoid of this frequency in ``residual``."""
    return np.linalg.lstsq(sinusoid_columns(t, frequency_hz), residual, rcond=None)[0]


def amplitude_at(residual: np.ndarray, t: np.ndarray, frequency_hz: float) -> float:
    """Least-squares amplitude of a sinusoid of this frequency in ``residual`` (phase free)."""
    return float(math.hypot(*sinusoid_fit(residual, t, frequency_hz)))


def lines_removed(screen, m: int, train_residual: np.ndarray, frequency_hz: float) -> np.ndarray:
    """Fold ``m``'s training residual with a sinusoid of this frequency fitted in each of its records."""
    times = [p.rows * p.record.dt for k, p in enumerate(screen.parts) if k != m]
    parts = training_parts(screen, m, train_residual)
    out = [r - sinusoid_columns(t, frequency_hz) @ sinusoid_fit(r, t, frequency_hz) for r, t in zip(parts, times)]
    return np.concatenate(out)


def training_parts(screen, m: int, train_residual: np.ndarray) -> list[np.ndarray]:
    """Fold ``m``'s residual on its training rows cut into its records (every record but ``m``, in order)."""
    sizes = [p.rows.size for k, p in enumerate(screen.parts) if k != m]
    return np.split(train_residual, np.cumsum(sizes)[:-1])


def fold_frequencies(screen, train_residuals: Sequence[np.ndarray], n_peaks: int = 5) -> list[float]:
    """A sinusoid's frequency on top of a primary cause, one per leave-one-record-out fold, each chosen on the
    other records alone, the way it is then scored (``on_top``): their null residuals' spectral peaks, each
    refined by a line search of ``loo_rss`` on the primary's residual on those records when fitted on them
    alone (``train_residuals``: one per fold, on its training rows, from ``selection.heldout_errors``)."""
    n = len(screen.parts)
    times = [p.rows * p.record.dt for p in screen.parts]
    out = []
    for m in range(n):
        others = [k for k in range(n) if k != m]
        residuals = training_parts(screen, m, train_residuals[m])
        rss = lambda g, o=others, r=residuals: loo_rss(r, [times[k] for k in o], g)  # noqa: E731
        out.append(best_frequency(screen, rss, n_peaks, others))
    return out


def loo_rss(residuals: Sequence[np.ndarray], times: Sequence[np.ndarray], frequency_hz: float) -> float:
    """What a sinusoid of this frequency leaves of the residuals when each record takes the amplitude of the
    others (rms) and fits only its phase, as a held-out record does; with one record, amplitude and phase its
    own."""
    amp = [amplitude_at(r, t, frequency_hz) for r, t in zip(residuals, times)]
    total = 0.0
    for k, (r, t) in enumerate(zip(residuals, times)):
        rest = [a for j, a in enumerate(amp) if j != k] or [amp[k]]
        left = r - phase_fitted(r, t, frequency_hz, float(np.sqrt(np.mean(np.square(rest)))))
        total += float(left @ left)
    return total


def on_top(screen, folds, e_primary: np.ndarray, train_residuals: Sequence[np.ndarray],
           frequency_hz: float | Sequence[float]) -> np.ndarray:
    """Out-of-fold residuals ``e_primary`` of a primary cause with a per-record sinusoid added: on each
    left-out record, the amplitude (rms over the other records) from the primary's residual on the other
    records when fitted on them alone (``train_residuals``, one per fold), the phase fitted there. The
    frequency: one for every fold, or one per fold (``fold_frequencies``: chosen without that fold's record)."""
    n = len(screen.parts)
    f = np.broadcast_to(np.asarray(frequency_hz, dtype=float), (n,))
    times = [p.rows * p.record.dt for p in screen.parts]
    e = e_primary.copy()
    for m in range(n):
        e[folds.tail(m)] = 0.0  # not held-out targets (``selection.Folds``)
        if not folds.is_scored(m):
            continue
        rows = folds.head(m)
        a = fold_amplitude(screen, m, train_residuals[m], f[m])
        e[rows] = e_primary[rows] - phase_fitted(e_primary[rows], times[m][:rows.stop - rows.start], f[m], a)
    return e


def fold_amplitude(screen, m: int, train_residual: np.ndarray, frequency_hz: float) -> float:
    """The amplitude fold ``m`` predicts its left-out record with: rms over its training records of the
    amplitude at the frequency in their residual (``train_residual``, on its training rows)."""
    others = [k for k in range(len(screen.parts)) if k != m]
    amp = [amplitude_at(r, screen.parts[k].rows * screen.parts[k].record.dt, frequency_hz)
           for k, r in zip(others, training_parts(screen, m, train_residual))]
    return float(np.sqrt(np.mean(np.square(amp))))


def on_top_estimates(screen, folds, e_primary: np.ndarray, train_residuals: Sequence[np.ndarray],
                     frequencies_hz: Sequence[float]) -> dict:
    """What a sinusoid scored by ``on_top`` with one frequency per fold stands for: the folds' mean frequency,
    the rms of their amplitudes, and each record's phase (from its own start) where it is left out, for the
    meaning checks (``Screen.limit_of``: cycles, drive lock); phases of the held-out targets only."""
    phases = []
    for m, f in enumerate(frequencies_hz):
        if not folds.is_scored(m):  # no held-out residual there
            continue
        p, rows = screen.parts[m], folds.head(m)
        a, b = sinusoid_fit(e_primary[rows], p.rows[:rows.stop - rows.start] * p.record.dt, f)
        phases.append(float(math.atan2(b, a)))
    amps = [fold_amplitude(screen, m, r, f) for m, (r, f) in enumerate(zip(train_residuals, frequencies_hz))]
    return {"frequency_hz": float(np.mean(frequencies_hz)), "amplitude": float(np.sqrt(np.mean(np.square(amps)))),
            "phase_rad_per_record": phases, "fold_frequencies_hz": [float(f) for f in frequencies_hz]}


class JointLine:
    """A part (its stacked design ``A``) fitted jointly with a line, one (sin, cos) pair per record, on the rows
    of ``records``. Fitted on the part's residual alone, a line close to a harmonic of the drive is partly
    taken up by the part first (a hysteresis model makes harmonics of its drive), so the line's amplitude comes
    out low and its frequency is pushed away from the harmonic; fitted jointly, the part's columns take only
    what the line does not. The line's columns are projected off the part's (``column_basis``)."""

    def __init__(self, screen, A: np.ndarray, records: Sequence[int]):
        starts = np.cumsum([0] + [p.rows.size for p in screen.parts])
        rows = np.concatenate([np.arange(starts[k], starts[k + 1]) for k in records])
        self.A, self.y = A[rows], screen.y[rows]
        self.Q = column_basis(self.A)
        self.r0 = self.y - self.Q @ (self.Q.T @ self.y)
        self.times = [screen.parts[k].rows * screen.parts[k].record.dt for k in records]
        self.cuts = np.cumsum([t.size for t in self.times])[:-1]

    def columns(self, frequency_hz: float) -> np.ndarray:
        S = np.zeros((self.y.size, 2 * len(self.times)))
        for j, (t, a) in enumerate(zip(self.times, np.concatenate([[0], self.cuts]))):
            S[a:a + t.size, 2 * j:2 * j + 2] = sinusoid_columns(t, frequency_hz)
        return S

    def fit(self, frequency_hz: float) -> tuple[np.ndarray, np.ndarray]:
        """(the line on these rows, the residual of the part alone: the line left in)."""
        S = self.columns(frequency_hz)
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
        amp = [amplitude_at(r, t, frequency_hz) for r, t in zip(self.parts(frequency_hz), self.times)]
        return float(np.sqrt(np.mean(np.square(amp))))


@dataclass
class FoldLines:
    """A line estimated jointly with a part on each fold's training records (``JointLine``) and scored on the
    left-out record, its phase fitted there: ``errors`` are the out-of-fold residuals (the line removed from
    each held-out record's scored rows), ``part_errors`` the part's own (fitted without the line),
    ``train_residuals`` per fold the joint fit's residual on its training rows, ``phases`` each scored record's
    phase from its own start."""

    errors: np.ndarray
    part_errors: np.ndarray
    frequencies_hz: list
    amplitudes: list
    train_residuals: list
    phases: list

    def estimates(self) -> dict:
        """What the line scored stands for (as ``on_top_estimates``): the folds' mean frequency, the rms of
        their amplitudes, each held-out record's phase from its own start."""
        return {"frequency_hz": float(np.mean(self.frequencies_hz)),
                "amplitude": float(np.sqrt(np.mean(np.square(self.amplitudes)))),
                "phase_rad_per_record": list(self.phases),
                "fold_frequencies_hz": [float(f) for f in self.frequencies_hz]}


def joint_line(screen, folds, design: Callable[[int], np.ndarray], frequencies_hz: Sequence[float] | None = None,
               n_peaks: int = 5) -> FoldLines:
    """Out-of-fold residuals of a part (``design(m)``: fold m's stacked design, all rows) with a line: on each
    fold's training records the part and the line are fitted jointly, the frequency (unless given, one per
    fold) chosen there as the fit on every record chooses it (``best_frequency`` of ``JointLine.loo_rss``);
    the left-out record is predicted by the part fitted on the training records alone, as in its own held-out
    score, and the line, with the training records' amplitude, takes its phase from the record's scored rows
    (``phase_fitted``). ``train_residuals``: the joint fit's."""
    n = len(screen.parts)
    e, part_e = np.zeros(screen.n), np.zeros(screen.n)
    freqs, amps, train, phases = [], [], [], []
    for m in range(n):
        others = [k for k in range(n) if k != m]
        A = design(m)
        line = JointLine(screen, A, others)
        f = float(frequencies_hz[m]) if frequencies_hz is not None else best_frequency(
            screen, line.loo_rss, n_peaks, others)
        fitted, with_line = line.fit(f)
        theta, _ = screen.solve(line.A, line.y)  # the part alone: a disturbance does not change what is driven
        test = folds.test(m)
        part_e[test] = screen.y[test] - A[test] @ theta
        part_e[folds.tail(m)] = 0.0
        a = line.amplitude(f)
        e[test] = part_e[test]
        if folds.is_scored(m):
            rows, t = folds.head(m), screen.parts[m].rows * screen.parts[m].record.dt
            t = t[:rows.stop - rows.start]
            e[rows] = part_e[rows] - phase_fitted(part_e[rows], t, f, a)
            s, c = sinusoid_fit(part_e[rows], t, f)
            phases.append(float(math.atan2(c, s)))
        freqs.append(f)
        amps.append(a)
        train.append(with_line - fitted)
    return FoldLines(e, part_e, freqs, amps, train, phases)


def drive_locked(screen, estimates: Mapping) -> bool:
    """A sinusoid within the spectral resolution (half a cycle over the longest record) of a harmonic of
    every record's drive whose phases in the records (each from its own start) agree within
    ``locked_phase`` rad, and which does not turn in phase from one drive period to the next (in the base
    model's residual, at the harmonic; ``residuals.harmonic_phase_turn``): a turn of more than
    ``locked_turn`` rad per period and ``locked_turn_z`` standard errors (policy fields) is a line off the
    harmonic, closer
    to it than the records resolve, not a misfit that the drive repeats."""
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
    """Whether each frequency is a harmonic of every identification record's drive (within tolerance):
    there a disturbance cannot be told from the model's misfit."""
    out = np.ones(f.shape, dtype=bool)
    for p in screen.parts:
        fd = p.record.frequency_hz
        if not fd:
            return np.zeros(f.shape, dtype=bool)
        k = np.maximum(np.round(f / fd), 1.0)
        out &= np.abs(f - k * fd) <= tolerance_hz
    return out
