"""Planted effects for the diagnosis's accuracy benchmark and tests, made WITHOUT the extension code.

``planted_case(kind, base, drive, seed)`` builds a dataset: a plant (the
Table 2 MRPIM, the virtual DEA's physics, or a real piezo recording), a
drive, an effect drawn at random, then noise. ``planted_case(kind,
seed=seed, dataset=DS)`` plants it on a user's dataset instead: its records,
roles, windows and drives as they are, its own noise (the nulls get white or
AR(1) noise on top, as on the piezo recording). Every effect has its own
functional form or numerical method, none shared with
``hysbench.models.extended`` (whose blocks are exact first-/second-order-hold
recursions from rest):

=================  ===========================================================================
effect             form (drawn ranges; y in the plant's units, p2p = its peak-to-peak)
=================  ===========================================================================
relaxation         y += c (h_tau * u), h = exp(-t/tau)/tau, trapezoidal FFT convolution;
                   tau log-uniform [0.2, 8] s, |c| p2p/(input span) x uniform [0.02, 0.12], random sign
delay              y(t - d) by a phase ramp in the frequency domain (padded with the rest output);
                   d uniform [3, 30] ms
resonance          x'' + 2 zeta w x' + w^2 x = w^2 y, scipy solve_ivp (RK45) from x = y(0) at rest
                   (records beyond 20 000 samples, a user's only: fixed-step RK4);
                   f_n log-uniform [2, 15] Hz, zeta uniform [0.05, 0.5]
creep              y += D ln(1 + t/t_c) / ln(1 + T/t_c) (logarithmic law, T the longest record);
                   t_c log-uniform [5, 50] s (slow: the vocabulary's creep), |D| p2p x uniform
                   [0.01, 0.08], random sign
interference       y += A sin(2 pi f t + phi_m), phi_m uniform per record;
                   f uniform [3, 40] Hz, A p2p x uniform [0.002, 0.015]
saturation         y -> min(y, top - q p2p); q uniform [0.02, 0.10]
gain modulation    y -> y (1 + e sin(2 pi t / T_m + phi)), t the session clock; e uniform [0.02, 0.08],
  (out of vocab.)  T_m uniform [15, 60] s
sensor nonlin.     y -> y + b (y - y_mid)^2 / p2p; b uniform [0.03, 0.12]
dead zone          y -> y_mid + sign(y - y_mid) max(|y - y_mid| - w, 0) (a sensor dead band);
                   w p2p x uniform [0.02, 0.08]
=================  ===========================================================================

The Table 2 MRPIM plant has one set of thresholds for every record, over the identification drives'
input range (eq. 8 for a model fitted to them; the protocol's sines and the triangles span 0.5-2.5 kV,
a multisine's fade-in may lower its peak).

p2p: the 0.5 - 99.5 % quantile range of the identification outputs (MRPIM's q V''
term spikes at a triangle's corners). Noise: white, sd p2p x uniform [0.001, 0.003]; the nulls also with AR(1)
noise, phi uniform [0.9, 0.99], the same marginal sd. ``strength``: the rms
of (effect - plain plant) over the identification records, in % of p2p (``strength_by_effect_pct``: each
effect's own, what it added to the output before it).
"""

from __future__ import annotations

import dataclasses
import math
import os
from typing import Callable

import numpy as np
from numba import njit
from scipy import signal
from scipy.integrate import solve_ivp

from hysbench.data.dataset import Dataset, Record, load_dataset, shared_datasets_root
from hysbench.data.excitations import HIGH_KV, LOW_KV, multisine, triangle
from hysbench.data.protocol import paper_voltage, period_samples
from hysbench.data.segments import input_minimum_from
from hysbench.data.virtual_dea import displacement_mm
from hysbench.models import get_model
from hysbench.models.errors import HysbenchError

VOCABULARY = ("relaxation", "delay", "resonance", "creep", "interference", "saturation")
OUT_OF_VOCABULARY = ("gain-modulation", "sensor-nonlinearity", "dead-zone")
NULLS = ("null-white", "null-ar1")
BASES = ("mrpim", "virtual-dea", "piezo")
DRIVES = ("sines", "triangles", "multisines")
RECORDED = "recorded"  # the drive of a user's dataset: its own records'
SHARED = shared_datasets_root()
PIEZO = SHARED / "piezo_sindy_1hz"
DT = 2e-3  # the synthetic bases' sample time (s)
FREQUENCIES = {0.1: "identification", 0.2: "validation", 0.4: "identification", 0.8: "validation",
               1.0: "identification"}
NOISE = (0.001, 0.003)


def _log_uniform(rng, lo, hi) -> float:
    return float(math.exp(rng.uniform(math.log(lo), math.log(hi))))


def draw(kind: str, rng: np.random.Generator, p2p: float, input_span: float = 2.0) -> dict:
    """The effect's parameters (see the module docstring)."""
    sign = float(rng.choice([-1.0, 1.0]))
    if kind == "relaxation":
        return {"tau_s": _log_uniform(rng, 0.2, 8.0), "weight": sign * p2p / input_span * rng.uniform(0.02, 0.12)}
    if kind == "delay":
        return {"delay_s": float(rng.uniform(0.003, 0.030))}
    if kind == "resonance":
        return {"natural_frequency_hz": _log_uniform(rng, 2.0, 15.0), "damping_ratio": float(rng.uniform(0.05, 0.5))}
    if kind == "creep":
        return {"t_c_s": _log_uniform(rng, 5.0, 50.0), "drift": sign * p2p * rng.uniform(0.01, 0.08)}
    if kind == "interference":
        return {"frequency_hz": float(rng.uniform(3.0, 40.0)), "amplitude": p2p * float(rng.uniform(0.002, 0.015))}
    if kind == "saturation":
        return {"clipped_fraction": float(rng.uniform(0.02, 0.10))}
    if kind == "gain-modulation":
        return {"depth": float(rng.uniform(0.02, 0.08)), "period_s": float(rng.uniform(15.0, 60.0)),
                "phase_rad": float(rng.uniform(0, 2 * math.pi))}
    if kind == "sensor-nonlinearity":
        return {"curvature": float(rng.uniform(0.03, 0.12))}
    if kind == "dead-zone":
        return {"half_width": p2p * float(rng.uniform(0.02, 0.08))}
    if kind in NULLS:
        return {"ar1": float(rng.uniform(0.9, 0.99))} if kind == "null-ar1" else {}
    raise HysbenchError(f"unknown effect {kind!r}")


# --- effects (independent functional forms) --------------------------------------------
def low_pass_convolution(u: np.ndarray, dt: float, tau: float) -> np.ndarray:
    """int_0^t exp(-(t-s)/tau)/tau u(s) ds by the trapezoidal rule (FFT convolution), from rest."""
    h = np.exp(-np.arange(u.size) * dt / tau) / tau
    full = signal.fftconvolve(u, h)[: u.size] * dt
    return full - 0.5 * dt * (u[0] * h + u * h[0])  # trapezoid: half weight at both ends


def fractional_delay(y: np.ndarray, dt: float, d: float, rest: float) -> np.ndarray:
    """y(t - d) by a linear phase in the frequency domain; before d the rest value."""
    pad = int(math.ceil(d / dt)) + 64
    ramp = np.linspace(y[-1], rest, 4 * pad)  # back to rest, so the circular shift wraps rest into the start
    x = np.concatenate([np.full(pad, rest), y, ramp])
    f = np.fft.rfftfreq(x.size, dt)
    shifted = np.fft.irfft(np.fft.rfft(x) * np.exp(-2j * np.pi * f * d), x.size)
    return shifted[pad:pad + y.size]


ADAPTIVE_MODE_SAMPLES = 20_000  # longer records: the mode by fixed-step RK4 (scipy's RK45 would take minutes)
RK4_STEP = 0.05  # the fixed RK4 step, in radians of the mode (w h)


@njit(cache=True)
def _mode_rk4(y, dt, w, zeta, substeps):
    """The mode's ODE by classical RK4, ``substeps`` equal steps per sample, y linear between samples."""
    x = np.empty(y.size)
    x[0] = pos = y[0]
    vel = 0.0
    h = dt / substeps
    for k in range(y.size - 1):
        slope = y[k + 1] - y[k]
        for j in range(substeps):
            ya = y[k] + slope * j / substeps
            yb = y[k] + slope * (j + 0.5) / substeps
            yc = y[k] + slope * (j + 1.0) / substeps
            a1, b1 = vel, w * w * (ya - pos) - 2 * zeta * w * vel
            p2, v2 = pos + 0.5 * h * a1, vel + 0.5 * h * b1
            a2, b2 = v2, w * w * (yb - p2) - 2 * zeta * w * v2
            p3, v3 = pos + 0.5 * h * a2, vel + 0.5 * h * b2
            a3, b3 = v3, w * w * (yb - p3) - 2 * zeta * w * v3
            p4, v4 = pos + h * a3, vel + h * b3
            a4, b4 = v4, w * w * (yc - p4) - 2 * zeta * w * v4
            pos += h / 6 * (a1 + 2 * a2 + 2 * a3 + a4)
            vel += h / 6 * (b1 + 2 * b2 + 2 * b3 + b4)
        x[k + 1] = pos
    return x


def mode_ode(y: np.ndarray, dt: float, fn: float, zeta: float) -> np.ndarray:
    """x'' + 2 zeta w x' + w^2 x = w^2 y(t) (y linear between samples) from x = y(0), x' = 0: scipy's
    adaptive RK45 up to ``ADAPTIVE_MODE_SAMPLES`` samples (every fixed base), a fixed-step RK4 beyond
    (a user's long records)."""
    w = 2 * math.pi * fn
    if y.size > ADAPTIVE_MODE_SAMPLES:
        return _mode_rk4(np.ascontiguousarray(y, dtype=float), dt, w, zeta, max(1, math.ceil(w * dt / RK4_STEP)))
    t = np.arange(y.size) * dt

    def rhs(s, state):
        return [state[1], w * w * (np.interp(s, t, y) - state[0]) - 2 * zeta * w * state[1]]

    sol = solve_ivp(rhs, (0.0, t[-1]), [y[0], 0.0], t_eval=t, method="RK45", rtol=1e-7, atol=1e-9,
                    max_step=min(dt * 4, 0.05 / fn))
    return sol.y[0]


def apply(kind: str, e: dict, t: np.ndarray, u: np.ndarray, y: np.ndarray, dt: float, stats: dict,
          rng: np.random.Generator) -> np.ndarray:
    """The output with the effect (``stats``: p2p, y_mid, top, longest record, session time offset)."""
    if kind == "relaxation":
        return y + e["weight"] * low_pass_convolution(u, dt, e["tau_s"])
    if kind == "delay":
        return fractional_delay(y, dt, e["delay_s"], rest=float(y[0]))
    if kind == "resonance":
        return mode_ode(y, dt, e["natural_frequency_hz"], e["damping_ratio"])
    if kind == "creep":
        return y + e["drift"] * np.log1p(t / e["t_c_s"]) / math.log1p(stats["longest_s"] / e["t_c_s"])
    if kind == "interference":
        return y + e["amplitude"] * np.sin(2 * math.pi * e["frequency_hz"] * t + rng.uniform(0, 2 * math.pi))
    if kind == "saturation":
        return np.minimum(y, stats["top"] - e["clipped_fraction"] * stats["p2p"])
    if kind == "gain-modulation":
        clock = t + stats["offset_s"]
        return y * (1.0 + e["depth"] * np.sin(2 * math.pi * clock / e["period_s"] + e["phase_rad"]))
    if kind == "sensor-nonlinearity":
        return y + e["curvature"] * (y - stats["y_mid"]) ** 2 / stats["p2p"]
    if kind == "dead-zone":
        c = stats["y_mid"]
        return c + np.sign(y - c) * np.maximum(np.abs(y - c) - e["half_width"], 0.0)
    return y.copy()


def noise(rng: np.random.Generator, n: int, sd: float, ar1: float = 0.0) -> np.ndarray:
    """White (ar1 = 0) or AR(1) noise of marginal sd ``sd``."""
    w = rng.normal(0.0, sd * math.sqrt(1.0 - ar1 * ar1), n)
    return signal.lfilter([1.0], [1.0, -ar1], w, zi=[rng.normal(0.0, sd) * ar1])[0] if ar1 else w


# --- bases and drives ---------------------------------------------------------------------
def _drive(drive: str, frequency: float, index: int, seed: int) -> np.ndarray:
    n_periods = 2
    if drive == "sines":
        t = np.arange(n_periods * period_samples(frequency, DT)) * DT
        return paper_voltage(t, frequency)
    if drive == "triangles":
        return triangle(frequency, n_periods / frequency, DT)
    if drive == "multisines":
        return multisine(15.0, DT, f_min=0.1, f_max=2.0, n_tones=12, seed=seed * 10 + index)
    raise HysbenchError(f"unknown drive {drive!r}; choose one of {', '.join(DRIVES)}")


def _plant(base: str, input_range: tuple[float, float] = (LOW_KV, HIGH_KV)) -> Callable[[np.ndarray], np.ndarray]:
    if base == "mrpim":
        model = get_model("mrpim")
        params = model.preset("paper")
        # one plant for every record: the thresholds r_i = (i-1)/N ||V||_inf over one fixed input range, not
        # each record's own peak (a plant cannot know a record's future maximum; a multisine's peak differs
        # per record)
        return lambda u: model.simulate(u, DT, params, input_range=input_range)
    if base == "virtual-dea":
        return lambda u: displacement_mm(u, DT)
    raise HysbenchError(f"unknown base {base!r}")


def piezo_available() -> bool:
    return (PIEZO / "dataset.toml").exists()


def _piezo_records() -> list[tuple[np.ndarray, np.ndarray, np.ndarray, str]]:
    """The real piezo recording (read in place) cut at input minima into two two-period identification
    records and a validation record (the rest, at least one period), resampled to 1 kHz."""
    ds = load_dataset(PIEZO)
    r = ds.records[0]
    step = max(1, int(round(1e-3 / r.dt)))
    t, u, y = r.t[::step], r.u[::step], r.y[::step]
    dt = float(t[1] - t[0])
    n_p = period_samples(1.0, dt)
    on = int(np.argmax(np.abs(u) > 1e-6 * np.max(np.abs(u)))) + n_p // 2  # skip the step at onset
    first = input_minimum_from(Record(PIEZO.name, t, u, y, frequency_hz=1.0), on)
    out = []
    for k, role in enumerate(("identification", "identification", "validation")):
        a = first + 2 * k * n_p
        b = min(a + 2 * n_p, u.size)
        if b - a < n_p:
            raise HysbenchError("the piezo recording is shorter than expected")
        out.append((np.arange(b - a) * dt, u[a:b].copy(), y[a:b].copy(), role))
    return out


def _records(base: str, drive: str, seed: int) -> list[tuple[np.ndarray, np.ndarray, np.ndarray, str, float | None]]:
    if base == "piezo":
        return [(t, u, y, role, 1.0) for t, u, y, role in _piezo_records()]
    out = []
    if drive == "multisines":
        roles = ("identification", "validation", "identification", "validation", "identification")
        drives = [_drive(drive, 0.0, i, seed) for i in range(len(roles))]
        # the MRPIM plant's thresholds over the identification drives' range, the one eq. 8 gives a model
        # fitted to them (the affine map puts a multisine on [0.5, 2.5] before its fade-in, which can lower
        # its peak: 2.41-2.49 kV; over the design range the base could not represent its own plant)
        ident = [u for u, role in zip(drives, roles) if role == "identification"]
        plant = _plant(base, (min(float(u.min()) for u in ident), max(float(u.max()) for u in ident)))
        for u, role in zip(drives, roles):
            out.append((np.arange(u.size) * DT, u, plant(u), role, None))
        return out
    plant = _plant(base)
    for i, (f, role) in enumerate(FREQUENCIES.items()):
        u = _drive(drive, f, i, seed)
        out.append((np.arange(u.size) * DT, u, plant(u), role, f))
    return out


def planted_case(kinds: tuple[str, ...], base: str = "mrpim", drive: str = "sines", seed: int = 0,
                 effects: dict | None = None,
                 dataset: Dataset | str | os.PathLike | None = None) -> tuple[Dataset, dict]:
    """(dataset, truth) with the effects ``kinds`` (one or two of VOCABULARY, one of OUT_OF_VOCABULARY, or
    a null) drawn with ``seed`` (``effects`` replaces the drawn parameters, by kind). ``truth["signals"]``:
    per effect and record file, what the effect added to the output before the noise (arrays; not JSON).
    With ``dataset`` (a Dataset or its folder) the effects are planted on its records, which keep their
    files, roles and windows; ``base`` is then the dataset's name and ``drive`` ``RECORDED``."""
    user = None
    if dataset is not None:
        user = dataset if isinstance(dataset, Dataset) else load_dataset(dataset)
        base, drive = user.name, RECORDED
        recs = [(r.t - r.t[0], r.u, r.y, r.role, r.frequency_hz) for r in user.records]
        stream = [int(seed), len(BASES), len(DRIVES)]  # one stream for every user's dataset
    else:
        recs = _records(base, drive, seed)
        stream = [int(seed), BASES.index(base), DRIVES.index(drive)]
    rng = np.random.default_rng(np.random.SeedSequence(stream))
    ident = np.concatenate([y for _, _, y, role, _ in recs if role == "identification"])
    bottom, top = (float(q) for q in np.quantile(ident, [0.005, 0.995]))  # robust to MRPIM's spikes on triangles
    p2p = top - bottom
    span = max(float(u.max()) for _, u, _, role, _ in recs if role == "identification") - min(
        float(u.min()) for _, u, _, role, _ in recs if role == "identification")
    stats = {"p2p": p2p, "top": top, "y_mid": 0.5 * (top + bottom), "offset_s": 0.0,
             "longest_s": max(t[-1] for t, *_ in recs)}
    drawn = {k: draw(k, rng, p2p, span) for k in kinds}
    drawn.update(effects or {})
    recorded = base == "piezo" or user is not None  # a recording has its own noise
    sd = p2p * float(rng.uniform(*NOISE)) if not recorded else 0.0
    ar1 = drawn.get("null-ar1", {}).get("ar1", 0.0)
    if recorded and kinds[0] in NULLS:  # a null on a recording: its own noise, plus white or coloured noise
        sd = p2p * float(rng.uniform(*NOISE))
    records, eff_ss, n_id = [], 0.0, 0
    each_ss = dict.fromkeys(kinds, 0.0)  # per effect: what it added, over the identification records
    signals = {k: {} for k in kinds}  # per effect and record: what it added (after the effects before it)
    for i, (t, u, y, role, f) in enumerate(recs):
        dt = float(t[1] - t[0])
        out = y
        if user is not None:
            file = user.records[i].file
        else:
            file = f"r{i}_{f:g}Hz.npz" if f else f"r{i}_{drive}.npz"
        for k in kinds:
            before = out
            out = apply(k, drawn[k], t, u, out, dt, stats, rng)
            signals[k][file] = out - before
        if role == "identification":
            eff_ss += float(np.sum((out - y) ** 2))
            for k in kinds:
                each_ss[k] += float(np.sum(signals[k][file] ** 2))
            n_id += y.size
        stats["offset_s"] += t[-1] + dt
        out = out + (noise(rng, y.size, sd, ar1) if sd > 0 else 0.0)
        if user is not None:
            records.append(dataclasses.replace(user.records[i], y=out))
        else:
            records.append(Record(file=file, t=t, u=u, y=out, role=role, frequency_hz=f))
    name = f"planted-{'+'.join(kinds)}-{base}-{drive}-{seed}"
    how = f"planted {', '.join(kinds)} (seed {seed}); hysbench.benchmarks.diagnosis_accuracy.planted"
    if user is not None:
        ds = dataclasses.replace(user, name=name, records=records, description=f"{user.name}, {how}", path=None)
    else:
        ds = Dataset(name=name, records=records, input_unit="V" if base == "piezo" else "kV",
                     output_unit="um" if base == "piezo" else "mm", description=f"{base} driven by {drive}, {how}")
    truth = {"kinds": list(kinds), "effects": drawn, "base": base, "drive": drive, "seed": int(seed), "noise_sd": sd,
             "p2p": p2p, "strength_pct": 100 * math.sqrt(eff_ss / max(n_id, 1)) / p2p, "longest_s": stats["longest_s"],
             "strength_by_effect_pct": {k: 100 * math.sqrt(v / max(n_id, 1)) / p2p for k, v in each_ss.items()},
             "signals": signals}
    if "saturation" in kinds:
        truth["saturation_level"] = top - drawn["saturation"]["clipped_fraction"] * p2p
    return ds, truth
