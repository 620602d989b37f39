"""Speed of the virtual DEA: simulating all seven records <= 20 s.

The seven records of the default dataset hold 3,010,250 samples (t = 0 through the
creep transition, then two stable periods). Also timed, without a target: generating the
whole dataset (each frequency simulated to 2000 s to find its creep transition, then the
sensor), and the ``viscoelastic`` model batched over 8 parameter sets on the four
identification records' scored windows (what an identifier calls: ``simulate_window_batch``,
warm-up crossed in 5-sample RK4 steps).
"""

import numpy as np

from hysbench.data import load_dataset
from hysbench.data import virtual_dea as vd
from hysbench.models import get_model

RECORDS = load_dataset(vd.default_dataset_path()).records
N_SAMPLES = sum(r.t.size for r in RECORDS)


def simulate_seven_records():
    return [vd.displacement_mm(r.u, r.dt) for r in RECORDS]


def test_simulate_seven_records(benchmark):
    simulate_seven_records()  # JIT warm-up / cache load
    benchmark.pedantic(simulate_seven_records, rounds=5, iterations=1)
    median = benchmark.stats.stats.median
    benchmark.extra_info.update(samples=N_SAMPLES, median_s=median, samples_per_s=N_SAMPLES / median)
    print(f"\nseven records ({N_SAMPLES:,} samples): {median:.2f} s, {N_SAMPLES / median:.3g} samples/s")
    assert median <= 20.0


def test_generate_dataset(benchmark):
    ds = benchmark.pedantic(vd.generate_dataset, rounds=2, iterations=1)
    assert len(ds.records) == 7
    print(f"\ngenerate the dataset: {benchmark.stats.stats.median:.2f} s")


def test_viscoelastic_batched_identification_records(benchmark):
    model = get_model("viscoelastic")
    base = model.pack(model.preset("virtual-dea"))
    P = base * np.exp(np.random.default_rng(0).uniform(-0.2, 0.2, (8, base.size)))
    ident = [r for r in RECORDS if r.role == "identification"]
    n = sum(r.t.size for r in ident)

    def run():
        return [model.simulate_window_batch(r.u, r.dt, P, r.scored) for r in ident]

    run()
    benchmark.pedantic(run, rounds=3, iterations=1)
    rate = 8 * n / benchmark.stats.stats.median
    benchmark.extra_info.update(set_samples_per_s=rate)
    print(f"\nviscoelastic x8 on the identification records ({n:,} samples): "
          f"{benchmark.stats.stats.median:.2f} s, {rate:.3g} set-samples/s")
