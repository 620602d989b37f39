"""Speed of the five baselines on the paper's protocol (seven frequencies, two
periods each: 179,500 samples), one parameter set and batched over 64.

No target is set; the figures are in docs/speed.md. Run with
`python -m pytest benchmarks/speed/bench_baselines.py --benchmark-only`.
"""

import numpy as np
import pytest
from hysbench.data.protocol import FREQUENCIES_HZ, SAMPLE_TIME_S, paper_voltage, protocol_time
from hysbench.models import DataScale, get_model

DT = SAMPLE_TIME_S
INPUTS = [paper_voltage(protocol_time(f, 2), f) for f in FREQUENCIES_HZ]
N_SAMPLES = sum(u.size for u in INPUTS)
BASELINES = ("elliptical", "dual-polynomial", "bouc-wen", "preisach", "rate-dependent-pi")


def parameter_sets(model, n, seed=0):
    lo, hi = model.bounds(DataScale(y=15.0))
    P = np.random.default_rng(seed).uniform(lo, hi, size=(n, model.n_params))
    if "gamma" in model.param_names and model.name == "bouc-wen":
        b, g = model.param_names.index("beta"), model.param_names.index("gamma")
        P[:, g] = np.maximum(P[:, g], -0.8 * P[:, b])
    return P


@pytest.mark.parametrize("name", BASELINES)
def test_single_set(benchmark, name):
    model = get_model(name)
    p = parameter_sets(model, 1)[0]

    def run():
        return [model.simulate(u, DT, p) for u in INPUTS]

    run()  # JIT warm-up
    benchmark.pedantic(run, rounds=20, iterations=1, warmup_rounds=2)
    benchmark.extra_info.update(samples=N_SAMPLES, median_ms=benchmark.stats.stats.median * 1e3)


@pytest.mark.parametrize("name", BASELINES)
def test_batch_of_64(benchmark, name):
    model = get_model(name)
    P = parameter_sets(model, 64)

    def run():
        return [model.simulate_batch(u, DT, P) for u in INPUTS]

    run()
    benchmark.pedantic(run, rounds=5, iterations=1, warmup_rounds=1)
    median = benchmark.stats.stats.median
    benchmark.extra_info.update(samples=N_SAMPLES, median_ms=median * 1e3, per_set_ms=median / 64 * 1e3)
