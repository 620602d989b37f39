"""Data sets the fitted model cannot reproduce (tests/test_posterior.py, benchmarks/speed/bench_posterior.py):
the virtual DEA's physics with drawn relaxation times and moduli, and MRPIM plus a planted
first-order relaxation written here, independent of any hysbench extension code."""

import dataclasses

import numpy as np

from hysbench.data import virtual_dea as vd
from hysbench.data.dataset import Dataset, Record
from hysbench.data.dea_sensor import LaserSensor
from hysbench.data.protocol import FREQUENCIES_HZ, paper_voltage, protocol_time, role_of, weight_of
from hysbench.identification.posterior import simulated_ar1_dataset

# reduced MRPIM's truth (tests/test_posterior.py) and the planted data's AR(1) noise
TRUTH = {"gamma": 0.0305, "lambda": -0.0317, "p1": 3.255, "p2": 0.9785, "q": 0.0251, "a1": -4.6812,
         "a2": 0.8303, "a3": 0.2917, "a4": 2.4706, "offset": 0.4419}


def first_order_lowpass(u, dt, tau):
    """x' = (u - x) / tau by backward Euler, at rest at u[0]: written here, independent of hysbench."""
    x = np.empty_like(u)
    x[0] = u[0]
    a = dt / (tau + dt)
    for k in range(1, u.size):
        x[k] = x[k - 1] + a * (u[k] - x[k - 1])
    return x


def planted_relaxation_dataset(k, model, dt=0.02, n_periods=3, params=None):
    """MRPIM (``params``, default the reduced model's TRUTH) + gain (lowpass_tau(u) - u) + AR(1) noise; tau log-uniform on [0.2, 5] s, gain on
    [0.5, 1.5] mm/kV, both drawn per data set."""
    rng = np.random.default_rng(3000 + k)
    tau, gain = float(np.exp(rng.uniform(np.log(0.2), np.log(5.0)))), float(rng.uniform(0.5, 1.5))
    ds = simulated_ar1_dataset(model, TRUTH if params is None else params, sigma=0.005, phi=0.9, seed=3000 + k, n_periods=n_periods, dt=dt)
    for r in ds.records:
        r.y = r.y + gain * (first_order_lowpass(r.u, r.dt, tau) - r.u)
    return ds


def virtual_dea_dataset(k, dt=0.02, n_periods=3):
    """The virtual DEA's physics (Gent-Maxwell, ``displacement_mm``) with its relaxation times and branch
    moduli scaled by factors drawn per data set (0.5-2 and 0.7-1.4), measured by its laser sensor."""
    rng = np.random.default_rng(4000 + k)
    t = vd.TRUTH
    params = dataclasses.replace(t, tau_k=tuple(v * float(np.exp(rng.uniform(np.log(0.5), np.log(2.0))))
                                                for v in t.tau_k),
                                 mu_k=tuple(v * float(rng.uniform(0.7, 1.4)) for v in t.mu_k))
    sensor = LaserSensor()
    records = []
    for f in FREQUENCIES_HZ:
        time_s = protocol_time(f, n_periods, dt)
        u = paper_voltage(time_s, f)
        y = sensor.measure(vd.displacement_mm(u, dt, params), rng)
        records.append(Record(file=f"f{f:g}Hz.npz", t=time_s, u=u, y=y, role=role_of(f), frequency_hz=f,
                              weight=weight_of(f)))
    return Dataset(name=f"virtual-dea-{k}", records=records, input_unit="kV", output_unit="mm")
