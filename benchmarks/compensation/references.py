"""Reference trajectories of the tracking benchmark (desired platform displacement, mm).

* ``sine-<f>Hz`` for the protocol's seven frequencies: y_r(t) = mid - half cos(2 pi f t)
  (eq. 1's shape, starting at its minimum), spanning ``SPAN`` (90 %) of the output range
  of the default dataset's stable loop at that frequency (its scored window), about its
  centre, as long as that record (through the creep transition), scored over the last
  ``STABLE_PERIODS`` periods. Why not 100 %: the plant reaches the loop's extremes only
  at the input limits, and a sine-shaped output near them needs inputs beyond (the loop
  is not a sine): the full range would score the limits, not the compensation.
* ``triangle`` (0.2 Hz), ``multisine`` (0.02-2 Hz) and ``random`` (band-limited to
  2 Hz): the drive shapes of ``hysbench.data.excitations`` mapped onto ``SPAN`` of the
  output range every stable loop spans (the intersection of the seven), ``LONG_S``
  seconds long, scored after ``SETTLE_S`` s (past the creep transition, about 420 s here).

Every reference starts at the plant's rest reading (0) and blends into its shape over
the first ``FADE_S`` seconds (``excitations.fade_in``, half-cosine): the actuator is at
rest when a run starts, and a reference that jumped to the loop's minimum would ask
the inverse for a jump of the input that the rate-dependent envelopes of MRPIM turn
into a play memory far outside the loops (the warm-up is not scored).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hysbench.data import excitations
from hysbench.data.dataset import Dataset
from hysbench.data.protocol import period_samples
from hysbench.data.virtual_dea import STABLE_PERIODS
from hysbench.models.errors import HysbenchError

LONG_S = 600.0
SETTLE_S = 450.0
FADE_S = 30.0
SPAN = 0.9
WAVEFORM_SEED = 0


@dataclass(frozen=True)
class Reference:
    """A desired output for the plant to track.

    Attributes
    ----------
    name : str
        The reference's name (e.g. "sine-1Hz"; the key of the results).
    y : numpy.ndarray
        The desired output, mm, one value per sample.
    scored : slice
        The samples scored (after the creep transition).
    """

    name: str
    y: np.ndarray
    scored: slice


def loop_range(record) -> tuple[float, float]:
    """(min, max) of a record's measured output over its scored window (the stable loop)."""
    y = record.y[record.scored]
    return float(np.min(y)), float(np.max(y))


def central(lo: float, hi: float, span: float = SPAN) -> tuple[float, float]:
    """The central ``span`` of [lo, hi]."""
    mid, half = 0.5 * (lo + hi), 0.5 * span * (hi - lo)
    return mid - half, mid + half


def references(dataset: Dataset, dt: float) -> list[Reference]:
    """The benchmark's references for a dataset recorded on the protocol (sines at its frequencies)."""
    sines = [r for r in dataset.records if r.frequency_hz]
    if not sines:
        raise HysbenchError(f"dataset {dataset.name!r}: no record names a drive frequency; the tracking "
                            "references need the protocol's sine records")
    out = []
    ranges = []
    n_fade = int(round(FADE_S / dt))
    for rec in sorted(sines, key=lambda r: r.frequency_hz):
        f = rec.frequency_hz
        ranges.append(loop_range(rec))
        lo, hi = central(*ranges[-1])
        t = np.arange(rec.u.size) * dt
        y = 0.5 * (lo + hi) - 0.5 * (hi - lo) * np.cos(2.0 * np.pi * f * t)
        n_period = period_samples(f, dt)
        out.append(Reference(f"sine-{f:g}Hz", excitations.fade_in(y, n_fade, 0.0),
                             slice(y.size - STABLE_PERIODS * n_period, y.size)))
    lo = max(r[0] for r in ranges)
    hi = min(r[1] for r in ranges)
    if not hi > lo:
        raise HysbenchError(f"dataset {dataset.name!r}: its stable loops share no output range")
    lo, hi = central(lo, hi)
    scored = slice(int(round(SETTLE_S / dt)), int(round(LONG_S / dt)))
    shapes = {
        "triangle": excitations.triangle(0.2, LONG_S, dt, low=lo, high=hi),
        "multisine": excitations.multisine(LONG_S, dt, f_min=0.02, f_max=2.0, low=lo, high=hi, seed=WAVEFORM_SEED),
        "random": excitations.band_limited_random(LONG_S, dt, f_max=2.0, low=lo, high=hi, seed=WAVEFORM_SEED),
    }
    out += [Reference(name, excitations.fade_in(y, n_fade, 0.0), scored) for name, y in shapes.items()]
    return out
