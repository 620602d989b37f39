"""A suggested experiment: the drive on which two fitted extensions' predictions differ most.

When two causes predict the held-out records equally well (a delay and a
short first-order lag under slow sines; creep and a slow relaxation), the
two fitted extended models are simulated on probe drives -- the protocol's
sine (eq. 1) and a triangle at log-spaced frequencies, and a multisine --
over the same input range, each from rest for three periods; the root mean
square of their difference over the last two periods (the first settles) is
the separation. The probe with the largest separation is the experiment to
run. Interference is not driven by the input: it is told apart by a record
with the drive held constant. Neither is creep: against creep, one more probe
holds the input at its lowest level (the rest) from the start, as long as the
multisine, scored over its whole length (a drift there is creep; a
relaxation of a constant input does not move).
"""

from __future__ import annotations

import math

import numpy as np

from hysbench.data.excitations import multisine
from hysbench.data.protocol import paper_voltage

from .candidates import Candidate

N_FREQUENCIES = 9
SAMPLES_PER_PERIOD = 2000


def _probe_frequencies(screen) -> np.ndarray:
    dt = min(p.record.dt for p in screen.parts)
    drive = [p.record.frequency_hz for p in screen.parts if p.record.frequency_hz]
    lo = 0.2 * min(drive) if drive else 0.01
    hi = min(0.02 / dt, 5.0 * (max(drive) if drive else 1.0))
    return np.exp(np.linspace(math.log(lo), math.log(max(hi, 2 * lo)), N_FREQUENCIES))


def separation(screen, a: Candidate, b: Candidate, u: np.ndarray, dt: float, settle: int) -> float:
    ya = a.model.simulate(u, dt, a.params, input_range=screen.input_range)
    yb = b.model.simulate(u, dt, b.params, input_range=screen.input_range)
    d = (ya - yb)[settle:]
    return float(np.sqrt(np.mean(d * d))) if d.size and np.all(np.isfinite(d)) else math.nan


def suggest(screen, a: Candidate, b: Candidate) -> dict:
    """{"drive", "frequency_hz", "separation" (output units, rms), "noise_sd", "probes": [...]}."""
    if "interference" in (a.cause, b.cause):
        return {"drive": "constant input (drive off)", "frequency_hz": None, "separation": None,
                "noise_sd": screen.noise_sd,
                "note": "an interference is not driven by the input: record with the drive held constant"}
    probes = []
    for f in _probe_frequencies(screen):
        dt = 1.0 / (f * SAMPLES_PER_PERIOD)
        t = np.arange(3 * SAMPLES_PER_PERIOD) * dt
        probes.append({"drive": "sine (eq. 1)", "frequency_hz": float(f),
                       "separation": separation(screen, a, b, paper_voltage(t, f), dt, SAMPLES_PER_PERIOD)})
    freqs = _probe_frequencies(screen)
    dt = 1.0 / (freqs[-1] * 20)
    duration = 3.0 / freqs[0]
    lo, hi = screen.input_range
    u = multisine(duration, dt, f_min=float(freqs[0]), f_max=float(freqs[-1]), low=lo, high=hi)
    probes.append({"drive": f"multisine {freqs[0]:.3g}-{freqs[-1]:.3g} Hz", "frequency_hz": None,
                   "separation": separation(screen, a, b, u, dt, u.size // 3)})
    if "creep" in (a.cause, b.cause):
        hold = np.full(u.size, float(lo))
        probes.append({"drive": f"input held at {lo:.3g} (the rest) for {duration:.3g} s", "frequency_hz": None,
                       "separation": separation(screen, a, b, hold, dt, 0)})
    finite = [p for p in probes if p["separation"] is not None and math.isfinite(p["separation"])]
    best = max(finite, key=lambda p: p["separation"]) if finite else {"drive": None, "frequency_hz": None,
                                                                       "separation": None}
    return {**best, "noise_sd": screen.noise_sd, "probes": probes}
