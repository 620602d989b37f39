"""Interference: a sinusoid unrelated to the drive, with its own phase in every record (a disturbance); on a
held-out record, and on the validation records that confirm it by its amplitude, only its phase is fitted."""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from ..candidates import DRIVE_LOCKED, Candidate, prominence
from ..cause import OUTPUT_UNIT, Cause, register
from ..lines import (amplitude_at, best_frequency, block_columns, drive_locked, fold_amplitude, fold_frequencies,
                     frequencies_agree, joint_line, JointLine, lines_removed, on_top, phase_fitted, rms, row_times)
from ..residuals import RecordResidual, coherent_spectrum, spectral_peaks
from ..heldout import out_of_fold


def same_line(screen, fold_estimates: Sequence[dict]) -> bool:
    """Whether the folds found one line: frequencies that agree (``frequencies_agree``) and amplitudes within
    ``line_amplitude`` of their mean."""
    f = np.array([e["interference_frequency"] for e in fold_estimates])
    a = np.array([e["amplitude"] for e in fold_estimates])
    return bool(frequencies_agree(screen, f) and a.mean() > 0 and np.ptp(a) <= screen.policy.line_amplitude * a.mean())


@register
class Interference(Cause):
    name = "interference"
    units = {"frequency_hz": "Hz", "amplitude": OUTPUT_UNIT}
    parameters = ("interference_frequency",)
    not_refined = ("interference_frequency",)  # searched over spectral peaks, not by a gradient step
    bounded = False
    separable = False
    disturbance = True

    def fit(self, screen, library: dict, max_order: int) -> list[Candidate]:
        """The line on every identification record, its frequency chosen as the folds choose theirs (``JointLine``;
        one amplitude for every record, the phase per record)."""
        base_rows = screen.design(screen.base, screen.base_nl)
        frequency_hz = best_frequency(screen, JointLine(screen, base_rows, range(len(screen.parts))).loo_rss)
        model = screen.extension(("interference",))
        theta, res = screen.solve(np.column_stack([base_rows, block_columns(row_times(screen), frequency_hz)]),
                                  screen.y)
        nb = len(screen.base_lin)
        pairs = theta[nb:].reshape(-1, 2)
        amplitude = rms(np.hypot(pairs[:, 0], pairs[:, 1]))
        params = {**screen.base_nl, **dict(zip(screen.base_lin, map(float, theta[:nb]))),
                  "interference_frequency": float(frequency_hz), "interference_amplitude": amplitude,
                  "interference_sin": amplitude, "interference_cos": 0.0}
        estimates = {"frequency_hz": float(frequency_hz), "amplitude": amplitude,
                     "phase_rad_per_record": [float(math.atan2(b, a)) for a, b in pairs]}
        k = len(screen.base.param_names) + 1 + 2 * len(screen.parts)
        return [screen._finish(Candidate("interference", "sinusoidal disturbance (phase per record)", model, params, k,
                                         float(res @ res), screen.n, estimates, n_effective=screen.n_effective,
                                         stage="fixed base"))]

    def row_columns(self, nonlinear, dt: float, rows: np.ndarray) -> dict:
        """Its (sin, cos) pair at the rows' times from the record's start."""
        phase = 2.0 * np.pi * nonlinear["interference_frequency"] * dt * rows
        return {"interference_sin": np.sin(phase), "interference_cos": np.cos(phase)}

    def library_terms(self, screen, y_hat_rows: np.ndarray):
        """A sinusoid at the pooled coherent spectrum's peak (none without a peak)."""
        dt = max(p.record.dt for p in screen.parts)  # below every record's Nyquist frequency
        f, amp = coherent_spectrum(screen.null_residuals(), 1.0 / screen.drive_time, 0.45 / dt)
        peak = spectral_peaks(f, prominence(amp), n=1)
        if not peak:
            return None
        f0 = peak[0][0]
        return ([f"sin {f0:.4g}Hz", f"cos {f0:.4g}Hz"],
                lambda r, y_hat, t: [np.sin(2 * np.pi * f0 * t), np.cos(2 * np.pi * f0 * t)], [None, None])

    def joint(self, screen, c: Candidate, max_nfev: int) -> Candidate:
        return c  # its phase is per record: the base is fitted jointly with it already

    def estimates(self, params, model) -> dict:
        amplitude = (params["interference_amplitude"] if "interference_amplitude" in params  # one phase per record
                     else math.hypot(float(params["interference_sin"]), float(params["interference_cos"])))
        return {"frequency_hz": float(params["interference_frequency"]), "amplitude": float(amplitude)}

    def bounds(self, screen, parameter: str, lo: float, hi: float) -> tuple[float, float]:
        return lo, min(hi, screen.nyquist)  # the samples show nothing faster

    def limit(self, screen, estimates) -> str:
        pol = screen.policy
        if estimates["frequency_hz"] * screen.shortest_span < pol.interference_min_cycles:
            return (f"fewer than {pol.interference_min_cycles:g} cycles in the shortest record "
                    f"({screen.shortest_span:.3g} s): with its phase free per record, a slower sinusoid is a "
                    "per-record drift, not a disturbance")
        return DRIVE_LOCKED if drive_locked(screen, estimates) else ""

    def heldout_errors(self, screen, folds, c: Candidate, refit: bool, train_residuals: list | None):
        """A line fitted jointly with the base (``lines.joint_line``); one locked to the drive (no disturbance but
        the base's misfit at a harmonic) on the base's own residual (``lines.on_top``)."""
        fixed = [c.params["interference_frequency"]] * folds.n
        base_rows = screen.design(screen.base, {k: c.params[k] for k in screen.base_nl_names})
        if c.limit == DRIVE_LOCKED:
            base_train = []
            e_base = out_of_fold(screen, folds, lambda m: base_rows, base_train)
            freqs = fold_frequencies(screen, base_train) if refit else fixed
            amps = [fold_amplitude(screen, m, base_train[m], freqs[m]) for m in range(folds.n)]
            if train_residuals is not None:
                train_residuals.extend(lines_removed(screen, m, base_train[m], freqs[m]) for m in range(folds.n))
            e = on_top(screen, folds, e_base, base_train, freqs)
        else:
            lines = joint_line(screen, folds, lambda m: base_rows, None if refit else fixed)
            freqs, amps, e = lines.frequencies_hz, lines.amplitudes, lines.errors
            if train_residuals is not None:
                train_residuals.extend(lines.train_residuals)
        return e, [{"interference_frequency": f, "amplitude": a} if refit else {"amplitude": a}
                   for f, a in zip(freqs, amps)]

    def fold_checks(self, screen, fold_estimates: list[dict]) -> dict:
        return {"same_line": same_line(screen, fold_estimates)}

    def on_validation(self, before: list, c: Candidate, policy) -> tuple[list, dict]:
        """Its amplitude on the validation records checked against ``c``'s (``interference_amplitude_tolerance``)."""
        f, amplitude = c.estimates["frequency_hz"], c.estimates["amplitude"]
        after, amps = [], []
        for rr in before:
            t = rr.record.t - rr.record.t[0]
            after.append(RecordResidual(rr.record, rr.prediction + phase_fitted(rr.residual, t, f, amplitude)))
            if rr.record.role == "validation":
                amps.append(amplitude_at(rr.residual, t, f))
        a_val = rms(amps) if amps else float("nan")
        return after, {"frequency_hz": f, "identification_amplitude": amplitude, "validation_amplitude": a_val,
                       "same_amplitude": bool(abs(a_val / amplitude - 1.0) <= policy.interference_amplitude_tolerance)}

    def spectrum_marker(self, parameters) -> float | None:
        return parameters["frequency_hz"]
