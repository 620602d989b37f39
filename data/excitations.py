"""Drive waveforms beyond the protocol's sines (one home for every generator that needs them).

Every function returns an input sampled every ``dt`` seconds for ``duration_s``
seconds, within [low, high] (the DEA's 0.5-2.5 kV by default). Triangles, decaying
sines and reversal curves start at ``low`` as eq. 1 does (V(0) = 0.5 kV); the random
drives start at the midpoint. Random waveforms take a seed and are reproducible.

* ``triangle``: linear up-down ramps between low and high, starting at low.
* ``multisine``: random-phase tones log-spaced over [f_min, f_max] (equal
  amplitudes), scaled affinely onto [low, high], faded in from the midpoint over
  the slowest tone's period or ``fade_s`` (half-cosine) so that it starts without a step.
* ``band_limited_random``: white Gaussian noise low-passed by zeroing FFT bins
  above f_max, scaled onto [low, high], faded in like the multisine.
* ``decaying_sine``: a sine about the midpoint whose amplitude shrinks
  geometrically from (high - low) / 2 to ``final_fraction`` of it: nested minor loops.
* ``reversal_curves``: first-order reversal curves: from ``high``, ramp down to a
  reversal point and back up to ``high``, for reversal points evenly spaced
  between high and low (ramps at a fixed rate): minor loops that share one end.

``drive_band`` reads the band of any sampled drive from its spectrum (for a record
without a nominal frequency).
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

from hysbench.models.errors import HysbenchError

LOW_KV = 0.5
HIGH_KV = 2.5
DRIVE_BAND_TAIL = 0.01  # drive_band: the share of a drive's power left out below f_lo and above f_hi


class ExcitationError(HysbenchError):
    """Bad options for a drive waveform."""


def _samples(duration_s: float, dt: float) -> int:
    if not (dt > 0 and duration_s > 0 and math.isfinite(duration_s) and math.isfinite(dt)):
        raise ExcitationError(f"duration and time step must be positive, got {duration_s!r} s and {dt!r} s")
    return int(round(duration_s / dt))


def _check_range(low: float, high: float) -> None:
    if not (math.isfinite(low) and math.isfinite(high) and high > low):
        raise ExcitationError(f"input range must have low < high, got [{low!r}, {high!r}]")


def _onto(x: np.ndarray, low: float, high: float) -> np.ndarray:
    """Affine map of x onto [low, high] (min -> low, max -> high)."""
    span = float(x.max() - x.min())
    if span == 0:
        return np.full_like(x, 0.5 * (low + high))
    return low + (x - x.min()) * (high - low) / span


def drive_band(u: np.ndarray, dt: float, tail: float = DRIVE_BAND_TAIL) -> tuple[float, float] | None:
    """(f_lo, f_hi): the lowest and highest frequencies (Hz) of a drive, each cutting off ``tail`` of its
    power (periodogram of u minus its mean), between the record's first bin 1 / (n dt) and Nyquist;
    None for a constant drive.

    The periodogram sees the record as periodic. A record whose end does not join its start (the step
    from its last sample to its first is larger than every step inside it) leaks power from that jump
    far above its band, which would overstate f_hi and so tighten every bound scaled by the drive's
    shortest period; f_hi is read after the line through the record's ends is taken out. That line adds
    power near the record's first bins, so f_lo is read from the record as it is (there leakage can only
    move f_lo down, which widens the band)."""
    x = np.asarray(u, dtype=float)
    if x.size < 4:
        return None
    f = np.fft.rfftfreq(x.size, dt)[1:]

    def share(v: np.ndarray) -> np.ndarray | None:
        power = np.abs(np.fft.rfft(v - v.mean()))[1:] ** 2
        total = float(power.sum())
        return np.cumsum(power) / total if total > 0 else None

    as_is = share(x)
    if as_is is None:
        return None
    joined = as_is
    if abs(x[0] - x[-1]) > np.abs(np.diff(x)).max():
        joined = share(x - np.linspace(x[0], x[-1], x.size))
        joined = as_is if joined is None else joined
    lo = float(f[int(np.searchsorted(as_is, tail))])
    hi = float(f[min(int(np.searchsorted(joined, 1.0 - tail)), f.size - 1)])
    return lo, max(hi, lo)


def shortest_period(u: np.ndarray, dt: float, frequency_hz: float | None = None) -> float:
    """A drive's shortest period (s): 1 / its nominal frequency, or else 1 / the high end of its band
    (``drive_band``), at most its duration (a constant drive: its duration)."""
    if frequency_hz:
        return 1.0 / frequency_hz
    duration = np.asarray(u).size * dt
    band = drive_band(u, dt)
    return duration if band is None else min(1.0 / band[1], duration)


def fade_in(u: np.ndarray, n_fade: int, start: float) -> np.ndarray:
    """Blend from the constant ``start`` into u over the first n_fade samples (half-cosine)."""
    n_fade = min(max(n_fade, 1), u.size)
    w = 0.5 - 0.5 * np.cos(np.pi * np.arange(n_fade) / n_fade)
    out = u.copy()
    out[:n_fade] = start + w * (u[:n_fade] - start)
    return out


def triangle(frequency_hz: float, duration_s: float, dt: float = 1e-3, low: float = LOW_KV,
             high: float = HIGH_KV) -> np.ndarray:
    _check_range(low, high)
    n = _samples(duration_s, dt)
    if not frequency_hz > 0:
        raise ExcitationError(f"frequency must be positive, got {frequency_hz!r}")
    phase = (np.arange(n) * dt * frequency_hz) % 1.0
    return low + (high - low) * (1.0 - np.abs(2.0 * phase - 1.0))


def multisine(duration_s: float, dt: float = 1e-3, f_min: float = 0.02, f_max: float = 2.0, n_tones: int = 20,
              low: float = LOW_KV, high: float = HIGH_KV, seed: int = 0, fade_s: float | None = None) -> np.ndarray:
    """``fade_s``: length of the fade-in (default: the slowest tone's period)."""
    _check_range(low, high)
    n = _samples(duration_s, dt)
    if not (0 < f_min < f_max < 0.5 / dt) or n_tones < 1:
        raise ExcitationError(f"multisine needs 0 < f_min < f_max < Nyquist and n_tones >= 1, got "
                              f"{f_min!r}, {f_max!r}, {n_tones!r}")
    rng = np.random.default_rng(seed)
    freqs = np.geomspace(f_min, f_max, n_tones)
    phases = rng.uniform(0.0, 2.0 * np.pi, n_tones)
    t = np.arange(n) * dt
    x = np.sin(2.0 * np.pi * freqs[:, None] * t[None, :] + phases[:, None]).sum(axis=0)
    u = _onto(x, low, high)
    return fade_in(u, int(round((1.0 / f_min if fade_s is None else fade_s) / dt)), 0.5 * (low + high))


def band_limited_random(duration_s: float, dt: float = 1e-3, f_max: float = 2.0, low: float = LOW_KV,
                        high: float = HIGH_KV, seed: int = 0) -> np.ndarray:
    _check_range(low, high)
    n = _samples(duration_s, dt)
    if not 0 < f_max < 0.5 / dt:
        raise ExcitationError(f"band limit must lie in (0, Nyquist), got {f_max!r} Hz")
    rng = np.random.default_rng(seed)
    spectrum = np.fft.rfft(rng.standard_normal(n))
    spectrum[np.fft.rfftfreq(n, dt) > f_max] = 0.0
    u = _onto(np.fft.irfft(spectrum, n), low, high)
    return fade_in(u, int(round(1.0 / (f_max * dt))), 0.5 * (low + high))


def decaying_sine(frequency_hz: float, duration_s: float, dt: float = 1e-3, final_fraction: float = 0.1,
                  low: float = LOW_KV, high: float = HIGH_KV) -> np.ndarray:
    _check_range(low, high)
    n = _samples(duration_s, dt)
    if not (frequency_hz > 0 and 0 < final_fraction <= 1):
        raise ExcitationError(f"decaying sine needs a positive frequency and 0 < final_fraction <= 1, got "
                              f"{frequency_hz!r}, {final_fraction!r}")
    t = np.arange(n) * dt
    amplitude = 0.5 * (high - low) * final_fraction ** (t / (n * dt))
    return 0.5 * (low + high) + amplitude * np.sin(2.0 * np.pi * frequency_hz * t - 0.5 * np.pi)


def reversal_curves(n_curves: int = 5, rate_per_s: float = 0.8, dt: float = 1e-3, low: float = LOW_KV,
                    high: float = HIGH_KV) -> np.ndarray:
    """First-order reversal curves; the length follows from the ramps (no duration argument)."""
    _check_range(low, high)
    if n_curves < 1 or not rate_per_s > 0:
        raise ExcitationError(f"reversal curves need n_curves >= 1 and a positive rate, got {n_curves!r}, "
                              f"{rate_per_s!r}")
    step = rate_per_s * dt

    def ramp(a, b):
        k = max(1, int(math.ceil(abs(b - a) / step)))
        return np.linspace(a, b, k + 1)[1:]

    parts = [ramp(low, high)]  # from rest at low up to the first turning point
    for reversal in np.linspace(high, low, n_curves + 1)[1:]:
        parts += [ramp(high, reversal), ramp(reversal, high)]
    return np.concatenate([[low], *parts])


# name -> (function, keyword arguments of the default drive for the virtual DEA)
EXCITATIONS: dict[str, tuple[Callable[..., np.ndarray], dict]] = {
    "triangle": (triangle, {"frequency_hz": 0.2, "duration_s": 60.0}),
    "multisine": (multisine, {"duration_s": 200.0}),
    "random": (band_limited_random, {"duration_s": 200.0}),
    "decaying-sine": (decaying_sine, {"frequency_hz": 0.2, "duration_s": 100.0}),
    "reversal-curves": (reversal_curves, {}),
}


def excitation(name: str, **overrides) -> np.ndarray:
    """A named drive with its defaults, some overridden."""
    try:
        function, defaults = EXCITATIONS[name]
    except KeyError:
        raise ExcitationError(f"unknown excitation {name!r}; known: {', '.join(EXCITATIONS)}") from None
    try:
        return function(**{**defaults, **overrides})
    except TypeError as exc:
        raise ExcitationError(f"bad options for excitation {name!r}: {exc}") from None
