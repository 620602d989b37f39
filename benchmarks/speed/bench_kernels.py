"""Speed of the play-operator kernels on the paper's protocol.

Targets (2-core machine): MRPIM over the seven-frequency protocol (two periods
per frequency: 179,500 samples, 13 operators) <= 2.5 ms median and >= 50x
faster than a NumPy per-sample loop timed in the same run; batched over 64
parameter sets >= 1e9 operator updates per second.
"""

import time

import numpy as np
import pytest

from hysbench.data.protocol import FREQUENCIES_HZ, SAMPLE_TIME_S, paper_voltage, protocol_time
from hysbench.models import get_model

DT = SAMPLE_TIME_S
INPUTS = [paper_voltage(protocol_time(f, 2), f) for f in FREQUENCIES_HZ]
N_SAMPLES = sum(u.size for u in INPUTS)
MODEL = get_model("mrpim")
PARAMS = MODEL.preset("paper")
N_OPS = MODEL.n_operators


def simulate_protocol():
    return [MODEL.simulate(u, DT, PARAMS) for u in INPUTS]


def numpy_per_sample(u, p):
    """The same model as a NumPy loop over samples (operators vectorised per step)."""
    r = np.arange(N_OPS) / N_OPS * np.max(np.abs(u))
    a = np.array([p[f"a{i}"] for i in range(1, N_OPS + 1)])
    w = np.zeros(N_OPS)
    y = np.empty(u.size)
    u1 = u2 = u[0]
    for k in range(u.size):
        du, ddu = (u[k] - u1) / DT, (u[k] - 2 * u1 + u2) / DT**2
        u2, u1 = u1, u[k]
        w = np.maximum(u[k] - p["gamma"] * abs(du) - r, np.minimum(u[k] + p["lambda"] * abs(du), w))
        y[k] = (p["p1"] * u[k] + p["p2"] * u[k] ** 2 + p["p3"] * u[k] ** 3 + p["p4"] * u[k] ** 4
                + p["q"] * ddu + a @ w)
    return y


def test_mrpim_protocol(benchmark):
    simulate_protocol()  # JIT warm-up
    ys = benchmark.pedantic(simulate_protocol, rounds=200, iterations=1, warmup_rounds=5)
    median = benchmark.stats.stats.median
    # NumPy reference on the 1 Hz record, scaled to the protocol's sample count
    u = INPUTS[-1]
    t0 = time.perf_counter()
    ref = numpy_per_sample(u, PARAMS)
    numpy_protocol_s = (time.perf_counter() - t0) * N_SAMPLES / u.size
    np.testing.assert_allclose(ys[-1], ref, rtol=1e-9, atol=1e-9)
    speedup = numpy_protocol_s / median
    benchmark.extra_info.update(median_ms=median * 1e3, numpy_loop_s=numpy_protocol_s, speedup=speedup)
    print(f"\nMRPIM protocol: median {median * 1e3:.3f} ms, NumPy loop {numpy_protocol_s:.2f} s, {speedup:.0f}x")
    assert median <= 2.5e-3
    assert speedup >= 50


@pytest.mark.parametrize("n_sets", [64])
def test_mrpim_batched(benchmark, n_sets):
    P = np.tile(MODEL.pack(PARAMS), (n_sets, 1))
    P[:, 0] *= np.linspace(0.5, 1.5, n_sets)  # distinct sets

    def run():
        return [MODEL.simulate_batch(u, DT, P) for u in INPUTS]

    run()
    benchmark.pedantic(run, rounds=10, iterations=1, warmup_rounds=1)
    rate = n_sets * N_SAMPLES * N_OPS / benchmark.stats.stats.median
    benchmark.extra_info.update(operator_updates_per_s=rate)
    print(f"\nbatched x{n_sets}: {rate:.3g} operator updates/s")
    assert rate >= 1e9
