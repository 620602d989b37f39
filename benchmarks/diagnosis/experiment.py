"""A suggested experiment: the probe drive (eq. 1's sine at log-spaced frequencies, a multisine, the input held
at rest) from rest on which two fitted extensions' predictions differ most (rms after settling), skipping probes
on which a fit leaves the recorded output range; an interference is told apart with the drive held constant.
"""

from __future__ import annotations

import math

import numpy as np

from hysbench.data.excitations import multisine
from hysbench.data.protocol import AMPLITUDE_KV, OFFSET_KV, paper_voltage, period_samples

from .candidates import Candidate

N_FREQUENCIES = 9
SAMPLES_PER_PERIOD = 2000
OUTSIDE_RECORDED = 1.0  # a probe's fit beyond the recorded output range by this many times its width
SAME_DRIVE = 0.02  # two inputs' quantiles agree within this share of their range: the same drive
_DRIVE_QUANTILES = (0.01, 0.25, 0.5, 0.75, 0.99)


def _whole_periods(record) -> np.ndarray:
    """The input over the whole drive periods at the start of the scored window (all of it if shorter than one)."""
    u = record.u[record.scored]
    n = period_samples(record.frequency_hz, record.dt) if record.dt > 0 else 0
    return u[: u.size // n * n] if 0 < n <= u.size else u


def one_drive(records) -> dict | None:
    """The drive every record shares (one frequency, and over the whole periods of the scored windows the same
    input quantiles within ``SAME_DRIVE`` of the input range), or None."""
    if not records or any(r.frequency_hz is None for r in records) or len({float(r.frequency_hz) for r in records}) > 1:
        return None
    q = np.array([np.quantile(_whole_periods(r), _DRIVE_QUANTILES) for r in records])
    width = float(q[:, -1].max() - q[:, 0].min())
    if not width > 0 or float(np.max(q.max(axis=0) - q.min(axis=0))) > SAME_DRIVE * width:
        return None
    return {"frequency_hz": float(records[0].frequency_hz), "input_low": float(q[:, 0].min()),
            "input_high": float(q[:, -1].max()), "records": len(records)}


def _probe_frequencies(screen) -> np.ndarray:
    dt = min(p.record.dt for p in screen.parts)
    drive = [p.record.frequency_hz for p in screen.parts if p.record.frequency_hz]
    lo = 0.2 * min(drive) if drive else 0.01
    hi = min(0.02 / dt, 5.0 * (max(drive) if drive else 1.0))
    return np.exp(np.linspace(math.log(lo), math.log(max(hi, 2 * lo)), N_FREQUENCIES))


def predict(screen, c: Candidate, u: np.ndarray, dt: float) -> np.ndarray:
    """A candidate's output for the drive ``u``; a clip on top of a kept part clips that part's output."""
    y = c.model.simulate(u, dt, {n: c.params[n] for n in c.model.param_names}, input_range=screen.input_range)
    return y if getattr(c, "clips", None) is None else c.kind.clip(c, y)


def probe_sine(t: np.ndarray, frequency_hz: float, low: float, high: float) -> np.ndarray:
    """Eq. 1's sine (from its lowest point) over the input range [low, high]: eq. 1 itself on 0.5-2.5 kV."""
    unit = (paper_voltage(t, frequency_hz) - (OFFSET_KV - AMPLITUDE_KV)) / (2 * AMPLITUDE_KV)
    return low + (high - low) * unit


def _probe(screen, a: Candidate, b: Candidate, u: np.ndarray, dt: float, settle: int,
           recorded: tuple[float, float]) -> dict:
    """A probe's separation, and whether a fit leaves the ``recorded`` output range by more than its width there
    (``OUTSIDE_RECORDED``): what the fits predict so far out, the records did not pin down."""
    ya, yb = predict(screen, a, u, dt), predict(screen, b, u, dt)
    d = (ya - yb)[settle:]
    sep = float(np.sqrt(np.mean(d * d))) if d.size and np.all(np.isfinite(d)) else math.nan
    lo, hi = recorded
    margin = OUTSIDE_RECORDED * (hi - lo)
    outside = not all(np.all(np.isfinite(y)) and y.min() >= lo - margin and y.max() <= hi + margin for y in (ya, yb))
    return {"separation": sep, "outside_recorded": bool(outside)}


def suggest(screen, a: Candidate, b: Candidate) -> dict:
    """{"drive", "frequency_hz", "separation" (output units, rms), "noise_sd", "probes": [...]}; probes on which a
    fit leaves the recorded output range (``_probe``) are not suggested ("note" says so if none is left)."""
    if a.kind.disturbance or b.kind.disturbance:
        return {"drive": "constant input (drive off)", "frequency_hz": None, "separation": None,
                "noise_sd": screen.noise_sd,
                "note": "an interference is not driven by the input: record with the drive held constant"}
    lo, hi = screen.input_range
    recorded = (min(float(np.min(p.record.y)) for p in screen.parts),
                max(float(np.max(p.record.y)) for p in screen.parts))  # the identification records' output range
    probes, freqs = [], _probe_frequencies(screen)
    for f in freqs:
        dt = 1.0 / (f * SAMPLES_PER_PERIOD)
        t = np.arange(3 * SAMPLES_PER_PERIOD) * dt
        probes.append({"drive": f"sine {lo:.3g}-{hi:.3g} (eq. 1's form)", "frequency_hz": float(f),
                       **_probe(screen, a, b, probe_sine(t, f, lo, hi), dt, SAMPLES_PER_PERIOD, recorded)})
    dt = 1.0 / (freqs[-1] * 20)
    duration = 3.0 / freqs[0]
    u = multisine(duration, dt, f_min=float(freqs[0]), f_max=float(freqs[-1]), low=lo, high=hi)
    probes.append({"drive": f"multisine {freqs[0]:.3g}-{freqs[-1]:.3g} Hz", "frequency_hz": None,
                   **_probe(screen, a, b, u, dt, u.size // 3, recorded)})
    if a.kind.shown_at_rest or b.kind.shown_at_rest:
        hold = np.full(u.size, float(lo))
        probes.append({"drive": f"input held at {lo:.3g} (the rest) for {duration:.3g} s", "frequency_hz": None,
                       **_probe(screen, a, b, hold, dt, 0, recorded)})
    finite = [p for p in probes if math.isfinite(p["separation"]) and not p["outside_recorded"]]
    if finite:
        return {**max(finite, key=lambda p: p["separation"]), "noise_sd": screen.noise_sd, "probes": probes}
    return {"drive": None, "frequency_hz": None, "separation": None, "noise_sd": screen.noise_sd, "probes": probes,
            "note": f"on every probe a fit leaves the recorded output range ({recorded[0]:.3g} to {recorded[1]:.3g}) "
                    "by more than its width: these records do not pin the fits down there, so no drive can be "
                    "suggested from them"}
