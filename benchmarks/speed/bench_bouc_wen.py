"""Speed of the Bouc-Wen oscillator on the benchmark's training record size (40,960 samples
at 750 Hz, 20 RK4 sub-steps each), one parameter set and batched over 8 (lsq's Jacobian
batch), and the whole identification on the benchmark (goal: <= 60 s).

Run with `python -m pytest benchmarks/speed/bench_bouc_wen.py --benchmark-only`; the
identification case is skipped when ../shared/datasets/bouc_wen_benchmark is absent.
"""

from pathlib import Path

import numpy as np
import pytest
from hysbench.benchmarks.reports.bouc_wen import DEFAULT_DATASET, TRUE_PARAMS, fit_oscillator
from hysbench.data.dataset import load_dataset
from hysbench.models import get_model

DT = 1.0 / 750.0
N = 40_960


def force(seed=0):
    rng = np.random.default_rng(seed)
    spec = np.zeros(N // 2 + 1, dtype=complex)
    f = np.fft.rfftfreq(N, DT)
    lines = (f >= 5.0) & (f <= 150.0)
    spec[lines] = np.exp(2j * np.pi * rng.random(lines.sum()))
    u = np.fft.irfft(spec, N)
    return 50.0 * u / np.std(u)


@pytest.mark.parametrize("n_sets", [1, 8])
def test_simulate(benchmark, n_sets):
    model = get_model("bouc-wen-oscillator")
    u = force()
    P = np.repeat(model.pack(TRUE_PARAMS)[None], n_sets, axis=0) * np.linspace(0.95, 1.05, n_sets)[:, None]
    model.simulate_batch(u, DT, P)  # JIT warm-up and the input's fine grid
    benchmark.pedantic(lambda: model.simulate_batch(u, DT, P), rounds=5, iterations=1, warmup_rounds=1)
    benchmark.extra_info.update(samples=N, n_sets=n_sets, median_ms=benchmark.stats.stats.median * 1e3)


def test_identification(benchmark):
    folder = Path(DEFAULT_DATASET)
    if not (folder / "dataset.toml").is_file():
        pytest.skip("Bouc-Wen benchmark data absent")
    ds = load_dataset(folder)
    row = benchmark.pedantic(lambda: fit_oscillator(ds, 0), rounds=1, iterations=1)
    benchmark.extra_info.update(seconds=row["seconds"], scores=row["scores"], target_s=60.0)
