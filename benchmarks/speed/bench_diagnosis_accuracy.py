"""The diagnosis's measured accuracy on planted effects: ``accuracy.run_accuracy``.

Not a CI test: 200 cases take 9-27 min with one process per core (as here) on 2-core hosts
(docs/speed.md).
``HYSBENCH_ACCURACY_CASES`` sets the number of cases (default 200); the
report goes to results/diagnosis_accuracy.md. The same run as a command:
``python3 -m hysbench.benchmarks.diagnosis.accuracy --cases 200 --out results --seed 40``
(``HEADLINE_SEED``).
"""

import os
from pathlib import Path

from hysbench.benchmarks.diagnosis.accuracy import HEADLINE_SEED, run_accuracy

RESULTS = Path(__file__).resolve().parents[2] / "results"


def test_diagnosis_accuracy(benchmark):
    n = int(os.environ.get("HYSBENCH_ACCURACY_CASES", "200"))
    summary = benchmark.pedantic(run_accuracy, args=(n,), kwargs={"seed": HEADLINE_SEED, "out": RESULTS,
                                                                  "jobs": os.cpu_count() or 1},
                                 rounds=1, iterations=1)
    print(f"\nverdict right {100 * summary['right_share']:.1f} % of {summary['cases']} cases; "
          f"confirmed causes on nulls {summary['confirmed_on_nulls']}; parameters within 25 % "
          f"{100 * summary['parameters_within_share']:.1f} %")
    assert summary["cases"] == n
