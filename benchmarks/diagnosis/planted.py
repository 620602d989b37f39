"""Data with one planted effect of the diagnosis vocabulary, for tests and demonstrations.

``planted_dataset(cause, seed)`` simulates the paper's Table 2 MRPIM on the
seven-frequency protocol (or fewer frequencies / periods) -- or, with
``source="virtual-dea"``, the virtual DEA's physics (``hysbench.data.virtual_dea``,
from rest, its own relaxation included) -- adds ONE effect
with its size and parameters drawn at random from the ranges below, then
white measurement noise. Each effect is computed here independently of the
extension models that the diagnosis fits (scipy.signal.lsim for the dynamic
blocks, the exact delayed input for the delay), so a test is not a model
checking itself.

Ranges (u in kV, y in mm; the Table 2 loops span about 1.6 to 6.4 mm, the
first period starts near -1.9 mm):

=============  =====================================================================
cause          drawn
=============  =====================================================================
none           nothing (noise only)
relaxation     y += c L_tau[u], L_tau first-order low-pass of u from rest;
               tau log-uniform in [0.3, 10] s, |c| uniform in [0.15, 0.5] mm/kV, random sign
delay          y(t) -> y(t - d), the actuator at rest (y = 0) before d; d uniform in [5, 40] ms
resonance      y -> H[y], H second-order low-pass of unit static gain from rest;
               f_n log-uniform in [2, 8] Hz, damping ratio uniform in [0.05, 0.4]
creep          y += s (1 - exp(-t / T_c)); T_c log-uniform in [2, 6] x the longest drive period
               ([100, 300] s on the full protocol), |s| uniform in [0.1, 0.5] mm, random sign
interference   y += A sin(2 pi f t + phi) in each record's own time; f uniform in [3, 40] Hz,
               A uniform in [0.02, 0.08] mm, phi uniform (the same in every record)
saturation     y -> min(y, level); level = (top of the scored loops) - q * (their range),
               q uniform in [0.03, 0.10]
=============  =====================================================================

Noise: white, sd uniform in [0.005, 0.015] mm (the virtual DEA's sensor has 0.01 mm).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np
from scipy import signal

from hysbench.data.protocol import (
    FREQUENCIES_HZ,
    SAMPLE_TIME_S,
    paper_voltage,
    protocol_time,
    role_of,
    weight_of,
)
from hysbench.data.dataset import Dataset, Record
from hysbench.models import CAUSES, get_model
from hysbench.models.errors import HysbenchError

PLANTABLE = ("none",) + CAUSES
NOISE_SD_RANGE = (0.005, 0.015)
RANGES = {
    "relaxation": {"tau_s": (0.3, 10.0), "weight_mm_per_kv": (0.15, 0.5)},
    "delay": {"delay_s": (0.005, 0.040)},
    "resonance": {"natural_frequency_hz": (2.0, 8.0), "damping_ratio": (0.05, 0.4)},
    "creep": {"time_scale_of_longest_period": (2.0, 6.0), "size": (0.1, 0.5)},
    "interference": {"frequency_hz": (3.0, 40.0), "amplitude": (0.02, 0.08)},
    "saturation": {"clipped_fraction_of_range": (0.03, 0.10)},
}


def _log_uniform(rng, lo, hi) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw_effect(cause: str, rng: np.random.Generator, longest_period_s: float = 50.0) -> dict:
    """The planted parameters, drawn from ``RANGES``."""
    if cause not in PLANTABLE:
        raise HysbenchError(f"unknown cause {cause!r}; choose one of {', '.join(PLANTABLE)}")
    r = RANGES.get(cause, {})
    if cause == "relaxation":
        return {"tau_s": [_log_uniform(rng, *r["tau_s"])],
                "weight": float(rng.choice([-1.0, 1.0]) * rng.uniform(*r["weight_mm_per_kv"]))}
    if cause == "delay":
        return {"delay_s": float(rng.uniform(*r["delay_s"]))}
    if cause == "resonance":
        return {"natural_frequency_hz": _log_uniform(rng, *r["natural_frequency_hz"]),
                "damping_ratio": float(rng.uniform(*r["damping_ratio"]))}
    if cause == "creep":
        lo, hi = r["time_scale_of_longest_period"]
        return {"time_scale_s": _log_uniform(rng, lo * longest_period_s, hi * longest_period_s),
                "size": float(rng.choice([-1.0, 1.0]) * rng.uniform(*r["size"]))}
    if cause == "interference":
        return {"frequency_hz": float(rng.uniform(*r["frequency_hz"])), "amplitude": float(rng.uniform(*r["amplitude"])),
                "phase_rad": float(rng.uniform(0.0, 2.0 * math.pi))}
    if cause == "saturation":
        return {"clipped_fraction_of_range": float(rng.uniform(*r["clipped_fraction_of_range"])), "side": "upper"}
    return {}


def _lsim(num, den, x: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Continuous-time transfer function from rest, input linear between samples."""
    _, y, _ = signal.lsim((num, den), x, t, interp=True)
    return np.asarray(y, dtype=float)


def apply_effect(cause: str, effect: dict, t: np.ndarray, u: np.ndarray, y: np.ndarray, frequency_hz: float,
                 simulate, dt: float) -> np.ndarray:
    """The noise-free output with the effect (``y`` is the plain model output on ``u``)."""
    if cause == "none":
        return y.copy()
    if cause == "relaxation":
        out = y.copy()
        for tau in effect["tau_s"]:
            out += effect["weight"] * _lsim([1.0], [tau, 1.0], u, t)
        return out
    if cause == "delay":
        d = effect["delay_s"]
        k0 = int(math.ceil(d / dt - 1e-12))
        out = np.zeros_like(y)  # at rest (zero output) until the delayed start
        if k0 < t.size:
            u_late = paper_voltage(t[k0:] - d, frequency_hz)  # the exact delayed input
            out[k0:] = simulate(u_late)
        return out
    if cause == "resonance":
        w = 2.0 * math.pi * effect["natural_frequency_hz"]
        return _lsim([w * w], [1.0, 2.0 * effect["damping_ratio"] * w, w * w], y, t)
    if cause == "creep":
        return y + effect["size"] * -np.expm1(-t / effect["time_scale_s"])
    if cause == "interference":
        return y + effect["amplitude"] * np.sin(2.0 * math.pi * effect["frequency_hz"] * t + effect["phase_rad"])
    if cause == "saturation":
        return np.minimum(y, effect["level"])
    raise HysbenchError(f"unknown cause {cause!r}")


SOURCES = ("mrpim", "virtual-dea")


def _source(source: str, dt: float):
    """simulate(u) -> y of the plant the effect is added to."""
    if source == "mrpim":
        model = get_model("mrpim")
        params = model.preset("paper")
        return lambda u: model.simulate(u, dt, params)
    if source == "virtual-dea":
        from hysbench.data.virtual_dea import displacement_mm

        return lambda u: displacement_mm(u, dt)
    raise HysbenchError(f"unknown source {source!r}; choose one of {', '.join(SOURCES)}")


def planted_dataset(cause: str, seed: int = 0, frequencies: Sequence[float] = FREQUENCIES_HZ,
                    n_periods: float = 2, dt: float | Mapping[float, float] = SAMPLE_TIME_S,
                    effect: dict | None = None, noise_sd: float | None = None,
                    source: str = "mrpim") -> tuple[Dataset, dict]:
    """(dataset, truth): the source plant on the protocol + one effect drawn with ``seed`` + noise.

    ``dt``: one sample time, or one per frequency ({frequency_hz: dt}; others get the protocol's).
    ``source``: "mrpim" (Table 2) or "virtual-dea" (its physics from rest).
    ``effect`` / ``noise_sd`` replace the drawn values (for demonstrations).
    Roles and weights follow Table 1; frequencies not in Table 1 are validation.
    """
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), PLANTABLE.index(cause) if cause in PLANTABLE else 99]))
    drawn = draw_effect(cause, rng, 1.0 / min(frequencies))
    effect = dict(effect) if effect is not None else drawn
    sd = float(noise_sd) if noise_sd is not None else float(rng.uniform(*NOISE_SD_RANGE))
    dt_of = (lambda f: float(dt.get(f, SAMPLE_TIME_S))) if isinstance(dt, Mapping) else (lambda f: float(dt))
    clean = []
    for f in frequencies:
        h = dt_of(f)
        simulate = _source(source, h)
        t = protocol_time(f, n_periods, h)
        u = paper_voltage(t, f)
        clean.append((f, t, u, simulate(u), simulate, h))
    if cause == "saturation" and "level" not in effect:
        tops = [y[-int(round(1.0 / (f * h))):] for f, _, _, y, _, h in clean]
        hi = max(float(np.max(s)) for s in tops)
        lo = min(float(np.min(s)) for s in tops)
        effect["level"] = hi - effect["clipped_fraction_of_range"] * (hi - lo)
    records = []
    for f, t, u, y, simulate, h in clean:
        y_eff = apply_effect(cause, effect, t, u, y, f, simulate, h)
        noise = rng.normal(0.0, sd, y.size)
        records.append(Record(file=f"f{f:g}Hz.npz", t=t, u=u, y=y_eff + noise, role=role_of(f), frequency_hz=f,
                              weight=weight_of(f)))
    if not any(r.role == "validation" for r in records) or not any(r.role == "identification" for r in records):
        raise HysbenchError("planted dataset: the frequencies must include identification and validation ones")
    plant = "Table 2 MRPIM" if source == "mrpim" else "the virtual DEA's physics"
    ds = Dataset(name=f"planted-{cause}-{seed}" + ("" if source == "mrpim" else "-dea"), records=records,
                 input_unit="kV", output_unit="mm",
                 description=f"{plant} on the paper's protocol with a planted {cause} effect (seed {seed}) "
                             f"and white noise sd {sd:.4g} mm; hysbench.benchmarks.diagnosis.planted")
    truth = {"cause": cause, "parameters": expected_parameters(cause, effect), "effect": effect, "noise_sd": sd,
             "seed": int(seed), "source": source}
    return ds, truth


def expected_parameters(cause: str, effect: dict) -> dict:
    """The planted effect in the diagnosis's report vocabulary."""
    if cause == "relaxation":
        return {"tau_s": list(effect["tau_s"])}
    if cause == "delay":
        return {"delay_s": effect["delay_s"]}
    if cause == "resonance":
        return {"natural_frequency_hz": effect["natural_frequency_hz"], "damping_ratio": effect["damping_ratio"]}
    if cause == "creep":
        return {"size": effect["size"], "time_scale_s": effect["time_scale_s"]}
    if cause == "interference":
        return {"frequency_hz": effect["frequency_hz"], "amplitude": effect["amplitude"]}
    if cause == "saturation":
        return {"level": effect["level"]}
    return {}
