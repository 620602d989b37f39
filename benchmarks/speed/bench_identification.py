"""Speed targets of the identifiers; pytest-benchmark, not collected by CI.

    python -m pytest benchmarks/speed/bench_identification.py -p no:cacheprovider

Targets, on this 2-core machine after JIT warm-up, over the identification
records of the default dataset (data/virtual_dea; until it exists, data
simulated from the paper's Table 2 MRPIM, two periods per frequency at 1 ms):

* varpro on MRPIM: <= 1 s wall for the whole ``identify`` call;
* mpso with its default budget (40 particles x 101 iterations): <= 60 s.

``HYSBENCH_BENCH_DATASET=DIR`` measures another dataset as "default". The
same are also measured on "long" synthetic records shaped like the virtual
DEA's (450 s per frequency from t = 0, the last period scored); those cases
report their time but assert nothing: the target is for the default dataset.
"""

from __future__ import annotations

import os

import numpy as np
import pytest

from hysbench.data.protocol import FREQUENCIES_HZ, paper_voltage, period_samples, role_of, weight_of
from hysbench.data.dataset import Dataset, Record, load_dataset
from hysbench.identification import identify
from hysbench.benchmarks.reports.identification import table2_dataset
from hysbench.data.virtual_dea import default_dataset_path
from hysbench.models import get_model

TARGET_SECONDS = {"varpro": 1.0, "mpso": 60.0}


def long_table2_dataset(duration_s: float = 450.0, noise_sd: float = 0.01, seed: int = 0) -> Dataset:
    """The protocol over whole periods filling ``duration_s`` from t = 0, last period scored."""
    model = get_model("mrpim", offset=False)
    params = model.preset("paper")
    rng = np.random.default_rng(seed)
    records = []
    for f in FREQUENCIES_HZ:
        n = period_samples(f) * int(np.ceil(duration_s * f))
        t = np.arange(n) * 1e-3
        u = paper_voltage(t, f)
        y = model.simulate(u, 1e-3, params) + rng.normal(0.0, noise_sd, n)
        records.append(Record(file=f"f{f:g}Hz.npz", t=t, u=u, y=y, role=role_of(f), frequency_hz=f,
                              weight=weight_of(f)))
    return Dataset("table2-long", records)


@pytest.fixture(scope="module", params=["default", "long-450s"])
def dataset(request):
    if request.param == "long-450s":
        return request.param, long_table2_dataset()
    path = os.environ.get("HYSBENCH_BENCH_DATASET") or default_dataset_path()  # the env var: another folder
    return request.param, (load_dataset(path) if path else table2_dataset())


@pytest.fixture(scope="module", autouse=True)
def warm_up():
    warm = Dataset("warm-up", [r for r in table2_dataset(1).records if r.frequency_hz in (0.4, 1.0)])
    identify("mrpim", warm, "varpro")
    identify("mrpim", warm, "mpso", swarm_size=4, iterations=1)


@pytest.mark.parametrize("method", ["varpro", "mpso"])
def test_identification_speed(benchmark, dataset, method):
    which, data = dataset
    n_samples = sum(r.u.size for r in data.identification)
    fit = benchmark.pedantic(identify, args=("mrpim", data, method), kwargs={"seed": 0},
                             rounds=3 if method == "varpro" else 1, iterations=1)
    seconds = benchmark.stats.stats.median
    benchmark.extra_info.update(dataset=which, identification_samples=n_samples, n_evaluations=fit.n_evaluations,
                                fitness=fit.fitness, fit_seconds=fit.fit_seconds, load_average=os.getloadavg()[0])
    print(f"\n{method} on {which} ({data.name}, {n_samples} identification samples): {seconds:.2f} s wall "
          f"(median identify() call; the last fit's own time {fit.fit_seconds:.2f} s), {fit.n_evaluations} "
          f"evaluations, fitness {fit.fitness:.4g}, load average {os.getloadavg()[0]:.1f}")
    if which == "default":
        assert seconds <= TARGET_SECONDS[method], f"{method}: {seconds:.2f} s > {TARGET_SECONDS[method]} s"
