r"""The virtual dielectric elastomer actuator: physics-based data that behaves like the paper's.

A lumped model of the paper's planar DEA (section 2.1): a prestretched VHB 4905
membrane (thickness H = 0.5 mm, prestretch 6 x 4) held by a frame, split by a
rigid platform into an active region (with electrodes) and a passive region.
Both regions deform in pure shear: the stretch lam along the actuation
direction varies, the transverse stretch lam_t is held by the frame, the
thickness stretch is 1/(lam lam_t) (incompressible). The platform's position
is the output; the voltage Phi across the active region is the input.

Material (per region), the Kelvin-Voigt-Maxwell form of Zhang et al. (Appl.
Phys. Lett. 110, 044104, 2017): a Gent spring (mu, J) in parallel with K
Gent-Maxwell branches (mu_k, J, relaxation time tau_k = eta_k / mu_k) and a
parallel dashpot (viscosity eta_v).

Nominal stresses along the actuation direction, per unit reference cross-section
(all stresses below are that, written s; I_1 is the first invariant):

    Gent spring       s_0 = mu / (1 - (I_1 - 3)/J) * (lam - lam^-3 lam_t^-2),
                      I_1 = lam^2 + lam_t^2 + lam^-2 lam_t^-2
    branch k          elastic stretches e_1 = lam/xi, e_2 = lam_t/xi_t, e_3 = 1/(e_1 e_2), with
                      (xi, xi_t) the branch's inelastic stretches;
                      s_k = mu_k / (1 - (e_1^2 + e_2^2 + e_3^2 - 3)/J) * (e_1^2 - e_3^2) / lam
    flow rule         (Zhao, Koh & Suo 2011: Newtonian dashpot driven by the deviatoric stress of the branch spring)
                      dxi/dt   / xi   = G_k (2 e_1^2 - e_2^2 - e_3^2) / (6 tau_k)
                      dxi_t/dt / xi_t = G_k (2 e_2^2 - e_1^2 - e_3^2) / (6 tau_k),
                      G_k = 1 / (1 - (e_1^2 + e_2^2 + e_3^2 - 3)/J)
    parallel dashpot  s_v = 4 eta_v (dlam/dt) / lam^2      (true stress 2 eta_v (D_1 - D_3), D_3 = -D_1)
    ideal dielectric  true Maxwell stress eps (Phi/h)^2, h = H / (lam lam_t), i.e. on the active region
                      s_M = eps Phi^2 lam lam_t^2 / H^2,  eps = eps_r eps_0

Geometry: unstretched lengths L_a (active) and L_p (passive) along the actuation
direction; the frame fixes L_a lam_a + L_p lam_p = (L_a + L_p) lam0, so
lam_p = lam0 - (L_a/L_p)(lam_a - lam0). Platform force balance (massless, at every instant):

    s_0(lam_a) + sum_k s_k,a + s_v,a - s_M  =  s_0(lam_p) + sum_k s_k,p + s_v,p,
    dlam_p/dt = -(L_a/L_p) dlam_a/dt,

which is linear in dlam_a/dt through the dashpots and so gives the state equation

    dlam_a/dt = [S_p - S_a + s_M] / [4 eta_v / lam_a^2 + (L_a/L_p) 4 eta_v / lam_p^2],

S the elastic stresses (spring + branches) of each region. The state is lam_a and
(xi, xi_t) of every branch of both regions (1 + 4K numbers); the output is the
platform displacement x = L_a (lam_a - lam0) in mm. At t = 0 the membrane rests at
the prestretch with every branch relaxed (xi = lam0, xi_t = lam_t); the voltage is
applied from t = 0 on (the protocol's V(0) = 0.5 kV). Integration: RK4 per 1 ms
sample with the voltage linearly interpolated (``dea_physics``).

Parameters (``TRUTH``) were calibrated by ``python -m hysbench.data.calibrate_virtual_dea``
against the paper's figures (section 2.3): see ``CALIBRATION_TARGETS``. The lumped
lengths are effective, not the platform geometry of the paper (see docs/datasets.md).

Sensor: ``dea_sensor.LaserSensor`` (0-100 mm on 0-10 V, 16-bit ADC, white noise).
Dataset: ``generate_dataset(seed)`` = the seven records of the paper's protocol,
each from t = 0 through the creep transition to two stable periods.
"""

from __future__ import annotations

import math
import os
import shutil
import tempfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hysbench.data.metrics import loop_width, peak_to_peak
from hysbench.data.protocol import (
    AMPLITUDE_KV,
    FREQUENCIES_HZ,
    OFFSET_KV,
    SAMPLE_TIME_S,
    period_samples,
    role_of,
    weight_of,
)
from hysbench.models.errors import HysbenchError

from hysbench.models import dea_physics
from hysbench.models.dea_physics import ISSUE_START, TRUTH, DEAParameters  # noqa: F401 (re-exported)
from .excitations import excitation
from .dataset import Dataset, Record, replace_folder, save_dataset
from .files import write_json
from .dea_sensor import LaserSensor

DATASET_NAME = "virtual-dea"
DEFAULT_SEED = 20180704
# The "final" cycle (the periodic steady state) is the last full period before this time.
FINAL_TIME_S = 2000.0
CREEP_TOLERANCE = 0.02  # cycle means within 2 % of the final peak-to-peak
STABLE_PERIODS = 2  # stable periods after the creep transition in every record

# The paper's figures (section 2.3) and the calibration's tolerances.
CALIBRATION_TARGETS = {
    "p2p_change_pct": (-27.3, 2.0),  # 0.02 -> 1 Hz, stable period
    "width_change_pct": (21.8, 3.0),
    "creep_transition_s": (400.0, 50.0),  # at 0.1 Hz
}


def branch_relaxation_times_s(params: DEAParameters = TRUTH) -> tuple[float, ...]:
    """The branches' material relaxation times tau_k = eta_k / mu_k (s): the truth a diagnosis can check."""
    return tuple(params.tau_k)


# --- simulation ------------------------------------------------------------------
def displacement_mm(u_kv, dt: float = SAMPLE_TIME_S, params: DEAParameters = TRUTH) -> np.ndarray:
    """Platform displacement (mm, from rest) for a voltage history in kV, sampled every dt s."""
    u = np.ascontiguousarray(u_kv, dtype=float)
    dlam = dea_physics.simulate_stretch(u, float(dt), params.vector(), params.n_branches)
    return 1e3 * params.L_active * dlam


def command_voltage(frequency_hz: float, n_samples: int, dt: float = SAMPLE_TIME_S) -> np.ndarray:
    """Eq. 1, V = sin(2 pi f t - pi/2) + 1.5 kV, at t_k = k dt, exactly periodic.

    One period is computed with the phase reduced to it (``math.sin``, not NumPy's
    vectorised sin, whose last bit may depend on the CPU) and repeated, so the
    signal is bitwise periodic; it equals ``protocol.paper_voltage`` to rounding.
    """
    n_period = period_samples(frequency_hz, dt)
    if abs(n_period * frequency_hz * dt - 1.0) > 1e-9:
        raise HysbenchError(f"a period of {frequency_hz:g} Hz is not a whole number of {dt:g} s samples")
    one = np.array([AMPLITUDE_KV * math.sin(2.0 * math.pi * k / n_period - 0.5 * math.pi) + OFFSET_KV
                    for k in range(n_period)])
    reps = -(-n_samples // n_period)
    return np.tile(one, reps)[:n_samples]


def cycle_means(y: np.ndarray, frequency_hz: float, dt: float = SAMPLE_TIME_S) -> np.ndarray:
    """Mean of y over each full period from t = 0."""
    n = period_samples(frequency_hz, dt)
    m = y.size // n
    return y[: m * n].reshape(m, n).mean(axis=1)


def creep_transition_s(y: np.ndarray, frequency_hz: float, dt: float = SAMPLE_TIME_S,
                       tolerance: float = CREEP_TOLERANCE) -> float:
    """End of the creep transition: the start of the first period from which every
    period's mean stays within ``tolerance`` x (peak-to-peak of the final period) of
    the final period's mean. The final period is the last full period of ``y``."""
    n = period_samples(frequency_hz, dt)
    means = cycle_means(y, frequency_hz, dt)
    last = y[(means.size - 1) * n: means.size * n]
    band = tolerance * peak_to_peak(last)
    outside = np.flatnonzero(np.abs(means - means[-1]) > band)
    first_inside = int(outside[-1]) + 1 if outside.size else 0
    return first_inside * n * dt


@dataclass
class FrequencyRun:
    """A noise-free run at one frequency, from t = 0 to the final period."""

    frequency_hz: float
    dt: float
    u: np.ndarray
    x: np.ndarray  # displacement, mm
    creep_transition_s: float = field(init=False)

    def __post_init__(self):
        self.creep_transition_s = creep_transition_s(self.x, self.frequency_hz, self.dt)

    @property
    def period(self) -> int:
        return period_samples(self.frequency_hz, self.dt)

    def final_loop(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.period
        m = self.x.size // n
        return self.u[(m - 1) * n: m * n], self.x[(m - 1) * n: m * n]

    @property
    def p2p(self) -> float:
        return peak_to_peak(self.final_loop()[1])

    @property
    def width(self) -> float:
        return loop_width(*self.final_loop())

    @property
    def record_periods(self) -> int:
        """Periods in the record: through the creep transition, then STABLE_PERIODS."""
        return int(round(self.creep_transition_s * self.frequency_hz)) + STABLE_PERIODS


def run_frequency(frequency_hz: float, params: DEAParameters = TRUTH, dt: float = SAMPLE_TIME_S,
                  final_time_s: float = FINAL_TIME_S) -> FrequencyRun:
    n_period = period_samples(frequency_hz, dt)
    n = (int(round(final_time_s / dt)) // n_period) * n_period
    u = command_voltage(frequency_hz, n, dt)
    return FrequencyRun(frequency_hz, dt, u, displacement_mm(u, dt, params))


def loop_asymmetry(u: np.ndarray, y: np.ndarray) -> float:
    """How far a loop is from point symmetry about its centre, in units of its peak-to-peak:
    (mean of the two branches at the middle input - middle of the output range) / p2p.
    0 for a loop symmetric under (u, y) -> (2 u_c - u, 2 y_c - y); y = u^2 over [0.5, 2.5] kV gives -1/6."""
    u, y = np.asarray(u, float), np.asarray(y, float)
    k0 = int(np.argmin(u))
    u, y = np.roll(u, -k0), np.roll(y, -k0)
    k1 = int(np.argmax(u))
    u_mid = 0.5 * (u.min() + u.max())
    asc = np.interp(u_mid, u[: k1 + 1], y[: k1 + 1])
    du, dy = u[k1:][::-1], y[k1:][::-1]  # descending branch, reversed to ascending input
    desc = np.interp(u_mid, du, dy)
    return float((0.5 * (asc + desc) - 0.5 * (y.max() + y.min())) / peak_to_peak(y))


def change_pct(first: float, last: float) -> float:
    return 100.0 * (last - first) / first


def calibration_figures(params: DEAParameters = TRUTH, dt: float = SAMPLE_TIME_S,
                        frequencies=FREQUENCIES_HZ, final_time_s: float = FINAL_TIME_S) -> dict:
    """The calibration figures in the periodic steady state (the final period of each run)."""
    runs = {f: run_frequency(f, params, dt, final_time_s) for f in frequencies}
    p2p = {f: r.p2p for f, r in runs.items()}
    width = {f: r.width for f, r in runs.items()}
    f0, f1 = frequencies[0], frequencies[-1]
    pv, wv = [p2p[f] for f in frequencies], [width[f] for f in frequencies]
    return {
        "p2p_mm": p2p,
        "width_mm": width,
        "p2p_change_pct": change_pct(p2p[f0], p2p[f1]),
        "width_change_pct": change_pct(width[f0], width[f1]),
        "p2p_monotone_decreasing": bool(np.all(np.diff(pv) < 0)),
        "width_monotone_increasing": bool(np.all(np.diff(wv) > 0)),
        "creep_transition_s": {f: r.creep_transition_s for f, r in runs.items()},
        "asymmetry": {f: loop_asymmetry(*r.final_loop()) for f, r in runs.items()},
        "max_displacement_mm": max(float(np.max(r.x)) for r in runs.values()),
        "min_displacement_mm": min(float(np.min(r.x)) for r in runs.values()),
        "runs": runs,
    }


# --- linearisation: the time constants an output-only diagnosis can see --------------------
@dataclass(frozen=True)
class ResponseMode:
    """One mode of the small-signal response of the displacement to the voltage."""

    tau_s: float  # time constant, s
    static_gain_share: float  # this mode's share of the static (DC) gain of x to u
    gain_mm_per_kv: float  # this mode's static gain: its step response is gain (1 - exp(-t/tau)) per kV


def response_modes(params: DEAParameters = TRUTH, u_kv: float = OFFSET_KV, settle_s: float = 3000.0,
                   min_share: float = 1e-6) -> tuple[ResponseMode, ...]:
    """Modes of the actuator linearised about its relaxed equilibrium at a constant voltage.

    The state Jacobian A and input vector B (finite differences) give x(s)/u(s) =
    sum_i r_i / (s - p_i); a mode is listed if its share of the static gain,
    (-r_i/p_i) / sum_j (-r_j/p_j), exceeds ``min_share``; ascending tau = -1/p_i.
    These, not the branches' material tau_k, are the time constants of the
    displacement: each branch relaxes against the rest of the structure, so its
    mode is slower than tau_k (and the dashpot adds a fast one).
    """
    p = params.vector()
    k = params.n_branches
    u0 = float(u_kv)
    dt = 0.01
    state = dea_physics.initial_state(p, k)
    dea_physics.simulate_from(np.full(int(settle_s / dt) + 1, u0), dt, p, k, state)

    def f(s, u):
        return dea_physics.state_derivative(s, u, p, k)

    n = state.size
    jac = np.empty((n, n))
    for j in range(n):
        h = 1e-6 * abs(state[j])
        up, dn = state.copy(), state.copy()
        up[j] += h
        dn[j] -= h
        jac[:, j] = (f(up, u0) - f(dn, u0)) / (2 * h)
    du = 1e-4
    b = (f(state, u0 + du) - f(state, u0 - du)) / (2 * du)
    poles, vecs = np.linalg.eig(jac)
    residues = vecs[0, :] * np.linalg.solve(vecs, b)
    dc = (-residues / poles).real
    share = dc / dc.sum()
    gain = dc * 1e3 * params.L_active  # d lam_a / d u_kv -> mm per kV
    modes = [ResponseMode(float(-1.0 / pl.real), float(sh), float(g)) for pl, sh, g in zip(poles, share, gain)
             if pl.real < 0 and abs(sh) > min_share]
    return tuple(sorted(modes, key=lambda m: m.tau_s))


# --- the dataset ----------------------------------------------------------------------
def default_dataset_path() -> Path:
    """data/virtual_dea/ of the source tree: the shipped default dataset."""
    return Path(__file__).resolve().parent / "virtual_dea"


def record_file(frequency_hz: float) -> str:
    return f"f{frequency_hz:g}Hz.npz"


def record_seed(seed: int, frequency_hz: float) -> np.random.SeedSequence:
    """Each record's noise has its own stream, so any record can be regenerated alone."""
    return np.random.SeedSequence([int(seed), int(round(frequency_hz * 1000))])


def generate_record(frequency_hz: float, seed: int = DEFAULT_SEED, params: DEAParameters = TRUTH,
                    sensor: LaserSensor = LaserSensor(), dt: float = SAMPLE_TIME_S,
                    run: FrequencyRun | None = None) -> Record:
    """One record: t = 0 through the creep transition, then two stable periods, measured."""
    run = run or run_frequency(frequency_hz, params, dt)
    n = run.record_periods * run.period
    if n > run.x.size:
        raise HysbenchError(f"{frequency_hz:g} Hz: the creep transition does not end before {FINAL_TIME_S:g} s")
    t = np.arange(n) * dt
    u = run.u[:n].copy()
    y = sensor.measure(run.x[:n], np.random.default_rng(record_seed(seed, frequency_hz)))
    window = (float((run.record_periods - 1) / frequency_hz), float(run.record_periods / frequency_hz))
    return Record(file=record_file(frequency_hz), t=t, u=u, y=y, role=role_of(frequency_hz),
                  frequency_hz=frequency_hz, weight=weight_of(frequency_hz), window=window)


def dataset_description(seed: int, params: DEAParameters, sensor: LaserSensor) -> str:
    taus = ", ".join(f"{t:g}" for t in params.tau_k)
    return (
        "Virtual DEA (hysbench.data.virtual_dea): Gent spring + Gent-Maxwell branches (tau_k = "
        f"{taus} s) + parallel dashpot, ideal dielectric, platform force balance; driven by eq. 1 at the "
        f"paper's seven frequencies from t = 0 through the creep transition to {STABLE_PERIODS} stable periods; "
        f"window = last period. Sensor: 0-100 mm on 0-10 V, 16-bit ADC (+-10 V, LSB {sensor.lsb_mm:.6g} mm), "
        f"white noise sd {sensor.noise_sd_mm:g} mm, 1 ms. Seed {seed}. Input: commanded voltage (kV), "
        "full precision. Output: displacement from rest (mm). Truth: truth.json."
    )


def generate(seed: int = DEFAULT_SEED, params: DEAParameters = TRUTH, sensor: LaserSensor = LaserSensor(),
             frequencies=FREQUENCIES_HZ, dt: float = SAMPLE_TIME_S) -> tuple[Dataset, dict[float, FrequencyRun]]:
    """The dataset and the noise-free runs it was measured from."""
    runs = {f: run_frequency(f, params, dt) for f in frequencies}
    records = [generate_record(f, seed, params, sensor, dt, run=runs[f]) for f in frequencies]
    ds = Dataset(name=DATASET_NAME, records=records, description=dataset_description(seed, params, sensor),
                 input_unit="kV", output_unit="mm")
    return ds, runs


def generate_dataset(seed: int = DEFAULT_SEED, params: DEAParameters = TRUTH, sensor: LaserSensor = LaserSensor(),
                     frequencies=FREQUENCIES_HZ, dt: float = SAMPLE_TIME_S) -> Dataset:
    """The seven records of the paper's protocol, measured by the sensor with the given seed."""
    return generate(seed, params, sensor, frequencies, dt)[0]


def truth(seed: int = DEFAULT_SEED, params: DEAParameters = TRUTH, sensor: LaserSensor = LaserSensor(),
          runs: dict[float, FrequencyRun] | None = None) -> dict:
    """What the dataset's truth file records: parameters, relaxation times, sensor, seed."""
    out = {
        "generator": "hysbench.data.virtual_dea",
        "seed": int(seed),
        "parameters": params.as_dict(),
        "branch_relaxation_times_s": list(branch_relaxation_times_s(params)),
        "response_modes_at_1.5kV": [{"tau_s": m.tau_s, "static_gain_share": m.static_gain_share,
                                     "gain_mm_per_kV": m.gain_mm_per_kv} for m in response_modes(params)],
        "sensor": sensor.as_dict(),
    }
    if runs is not None:
        out["records"] = {
            record_file(f): {"creep_transition_s": r.creep_transition_s, "periods": r.record_periods,
                             "samples": r.record_periods * r.period, "steady_state_p2p_mm": r.p2p,
                             "steady_state_width_mm": r.width}
            for f, r in runs.items()
        }
    return out


def write_dataset(folder: str | os.PathLike, seed: int = DEFAULT_SEED, params: DEAParameters = TRUTH,
                  sensor: LaserSensor = LaserSensor()) -> Path:
    """Generate and write the dataset (records as compressed .npz, dataset.toml, truth.json), atomically."""
    ds, runs = generate(seed, params, sensor)
    return _write_folder(Path(folder), ds, truth(seed, params, sensor, runs))


def _write_folder(folder: Path, ds: Dataset, truth_dict: dict) -> Path:
    """Records, dataset.toml and truth.json, built beside ``folder`` and moved into place."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.build.", dir=folder.parent))
    try:
        save_dataset(ds, tmp / "ds", compress=True)
        write_json(tmp / "ds" / "truth.json", truth_dict)
        replace_folder(tmp / "ds", folder)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return folder


# --- unseen waveforms: the same actuator and sensor under other drives ------------------------
# Every record starts at rest, is driven by eq. 1 at RUN_IN_HZ for RUN_IN_S (the seen sine, through most
# of the creep transition) and then by the unseen drive; only the unseen drive is scored (its window).
# The run-in ends at the phase where the sine meets the drive's first value (rising), so there is no step.
WAVEFORMS_NAME = "virtual-dea-waveforms"
RUN_IN_HZ = 0.2
RUN_IN_S = 250.0
COMMAND_STEP_KV = 2.0**-16  # the command is quantised (a 16-bit-DAC-like step) so that the records compress
# excitation name -> overrides of its defaults in data/excitations.py (short, to keep the shipped data small)
WAVEFORM_DRIVES = {
    "triangle": {"frequency_hz": 0.2, "duration_s": 30.0},
    "multisine": {"duration_s": 100.0, "fade_s": 2.0},
    "random": {"duration_s": 100.0},
    "decaying-sine": {"frequency_hz": 0.2, "duration_s": 50.0},
    "reversal-curves": {},
}


def default_waveforms_path() -> Path:
    """data/virtual_dea_waveforms/ of the source tree: the shipped unseen-waveform dataset."""
    return Path(__file__).resolve().parent / "virtual_dea_waveforms"


def waveform_command(name: str, dt: float = SAMPLE_TIME_S) -> tuple[np.ndarray, int]:
    """(command voltage in kV, samples of the sine run-in before the unseen drive ``name`` starts)."""
    drive = excitation(name, dt=dt, **WAVEFORM_DRIVES.get(name, {}))
    n_period = period_samples(RUN_IN_HZ, dt)
    level = min(max((drive[0] - OFFSET_KV) / AMPLITUDE_KV, -1.0), 1.0)
    phase = (math.asin(level) + 0.5 * math.pi) / (2.0 * math.pi)  # eq. 1 rises through drive[0] here
    n_run_in = int(round(RUN_IN_S * RUN_IN_HZ)) * n_period + int(round(phase * n_period))
    u = np.concatenate([command_voltage(RUN_IN_HZ, n_run_in, dt), drive])
    return np.round(u / COMMAND_STEP_KV) * COMMAND_STEP_KV, n_run_in


def waveform_seed(seed: int, name: str) -> np.random.SeedSequence:
    return np.random.SeedSequence([int(seed), zlib.crc32(name.encode())])


def generate_waveform_record(name: str, seed: int = DEFAULT_SEED, params: DEAParameters = TRUTH,
                             sensor: LaserSensor = LaserSensor(), dt: float = SAMPLE_TIME_S) -> Record:
    """One unseen-waveform record: the physics and the sensor under the run-in and the drive ``name``;
    a validation record (nothing is fitted on it) scored on the drive only."""
    u, n_run_in = waveform_command(name, dt)
    y = sensor.measure(displacement_mm(u, dt, params), np.random.default_rng(waveform_seed(seed, name)))
    t = np.arange(u.size) * dt
    return Record(file=f"{name}.npz", t=t, u=u, y=y, role="validation", weight=1.0,
                  window=(float(n_run_in * dt), float(u.size * dt)))


def write_waveform_dataset(folder: str | os.PathLike, names=None, seed: int = DEFAULT_SEED,
                           params: DEAParameters = TRUTH, sensor: LaserSensor = LaserSensor()) -> Path:
    """The unseen-waveform dataset (default: every drive of WAVEFORM_DRIVES), written atomically."""
    names = list(names or WAVEFORM_DRIVES)
    records = [generate_waveform_record(n, seed, params, sensor) for n in names]
    description = (
        f"Virtual DEA under drives it is not identified on ({', '.join(names)}), 0.5-2.5 kV, 1 ms. Each record: "
        f"eq. 1 at {RUN_IN_HZ:g} Hz from rest for about {RUN_IN_S:g} s (through most of the creep transition), "
        "then the drive; window = the drive. Same physics and sensor as virtual-dea; command quantised to "
        f"2^-16 kV. Seed {seed}. Truth: truth.json.")
    ds = Dataset(name=WAVEFORMS_NAME, records=records, description=description, input_unit="kV", output_unit="mm")
    truth_dict = {**truth(seed, params, sensor), "generator": "hysbench.data.virtual_dea.write_waveform_dataset",
                  "run_in": {"frequency_hz": RUN_IN_HZ, "seconds": RUN_IN_S},
                  "drives": {n: WAVEFORM_DRIVES.get(n, {}) for n in names},
                  "records": {r.file: {"run_in_samples": r.start, "samples": r.t.size} for r in records}}
    return _write_folder(Path(folder), ds, truth_dict)
