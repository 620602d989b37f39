"""The plant: the virtual DEA's physics with its laser sensor, stepped sample by sample.

The actuator is ``hysbench.models.dea_physics`` with the calibrated ``TRUTH`` (the
data generator's physics, no model of the model interface); its output is read by
``hysbench.data.dea_sensor.LaserSensor`` (noise, 16-bit ADC). Its input is limited to
0.5-2.5 kV: every command is clipped there and the clipped samples are counted.

Timing (one kernel for open and closed loop): at t_k the sensor reads the platform;
the controller computes the command for t_{k+1} from the readings up to t_k (one
sample of computation delay in the feedback path), and the actuator integrates
[t_k, t_{k+1}] with the voltage linear from u_k to u_{k+1}, as the data generator does
(first-order hold). With no feedback (kp = ki = 0) this is exactly the generator's
open-loop run. PI: u_{k+1} = clip(ff_{k+1} + kp e_k + I_k), I_k = I_{k-1} + ki dt e_k,
e_k = r_k - y_k; the integrator is held while the command is clipped in the
direction the error pushes it (conditional integration: no wind-up).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numba import njit

from hysbench.data.dea_sensor import LaserSensor, read_sample
from hysbench.data.protocol import SAMPLE_TIME_S
from hysbench.data.virtual_dea import DEFAULT_SEED
from hysbench.models import dea_physics
from hysbench.models.dea_physics import TRUTH, DEAParameters
from hysbench.models.errors import HysbenchError

U_MIN_KV = 0.5
U_MAX_KV = 2.5


@njit(cache=True)
def run_loop(reference, feedforward, kp, ki, u_lo, u_hi, dt, phys, n_br, noise, rest_mm, mm_per_volt,
             full_scale_v, lsb_v, rest_code, lsb_mm):
    """(u, y, x_mm, clipped): the plant from rest under feedforward + PI (see the module docstring)."""
    n = reference.shape[0]
    u = np.empty(n)
    y = np.full(n, np.nan)
    x_mm = np.full(n, np.nan)
    clipped = np.zeros(n, dtype=np.bool_)
    state = dea_physics.initial_state(phys, n_br)
    scale = 1e3 * phys[5]  # mm per unit stretch of the active region
    lam0 = phys[3]
    u[0] = min(max(feedforward[0], u_lo), u_hi)
    clipped[0] = u[0] != feedforward[0]
    m = dea_physics.substeps(u[0], dt, phys, n_br)
    integral = 0.0
    for k in range(n):
        x_mm[k] = scale * (state[0] - lam0)
        y[k] = read_sample(x_mm[k], noise[k], rest_mm, mm_per_volt, full_scale_v, lsb_v, rest_code, lsb_mm)
        if k == n - 1:
            break
        e = reference[k] - y[k]
        trial = integral + ki * dt * e
        v = feedforward[k + 1] + kp * e + trial
        if not ((v > u_hi and e > 0) or (v < u_lo and e < 0)):
            integral = trial
        v = feedforward[k + 1] + kp * e + integral
        u[k + 1] = min(max(v, u_lo), u_hi)
        clipped[k + 1] = u[k + 1] != v
        if not dea_physics.advance_sample(state, u[k], u[k + 1], dt, m, phys, n_br) or not np.isfinite(state[0]):
            u[k + 1:] = np.nan
            break
    return u, y, x_mm, clipped


@dataclass
class PlantRun:
    """One run of the plant: commanded input, sensor output, true displacement, clipped commands."""

    u: np.ndarray
    y: np.ndarray
    x: np.ndarray
    clipped: np.ndarray


@dataclass
class DEAPlant:
    """The virtual DEA + sensor with input limits; ``seed`` fixes the sensor noise of every run."""

    params: DEAParameters = TRUTH
    sensor: LaserSensor = field(default_factory=LaserSensor)
    dt: float = SAMPLE_TIME_S
    u_limits: tuple[float, float] = (U_MIN_KV, U_MAX_KV)
    seed: int = DEFAULT_SEED

    def run(self, reference, feedforward, kp: float = 0.0, ki: float = 0.0) -> PlantRun:
        """From rest: feedforward (the open-loop command) plus a PI on the reading (kp = ki = 0: open loop)."""
        r = np.ascontiguousarray(reference, dtype=float)
        ff = np.ascontiguousarray(feedforward, dtype=float)
        if r.shape != ff.shape or r.ndim != 1 or r.size < 2 or not (np.all(np.isfinite(r)) and np.all(np.isfinite(ff))):
            raise HysbenchError("plant: reference and feedforward must be finite 1-D arrays of one length (>= 2)")
        noise = self.sensor.noise_volts(r.size, np.random.default_rng(self.seed))
        u, y, x, clipped = run_loop(r, ff, float(kp), float(ki), *map(float, self.u_limits), float(self.dt),
                                    self.params.vector(), self.params.n_branches, noise, *self.sensor.constants())
        return PlantRun(u, y, x, clipped)


@dataclass
class ModelPlant:
    """A fitted model (plus the sensor's noise level, white, in output units) as the plant: open loop only.
    For the check that compensating a plant that IS the identified model leaves only the noise."""

    model: object
    params: dict
    input_range: tuple[float, float]
    noise_sd: float = 0.0
    dt: float = SAMPLE_TIME_S
    u_limits: tuple[float, float] = (U_MIN_KV, U_MAX_KV)
    seed: int = 0

    def run(self, reference, feedforward, kp: float = 0.0, ki: float = 0.0) -> PlantRun:
        if kp or ki:
            raise HysbenchError("a model plant runs open loop only")
        ff = np.asarray(feedforward, dtype=float)
        u = np.clip(ff, *self.u_limits)
        x = self.model.simulate(u, self.dt, self.params, input_range=self.input_range)
        y = x + np.random.default_rng(self.seed).normal(0.0, self.noise_sd, x.size) if self.noise_sd else x
        return PlantRun(u, y, x, u != ff)
