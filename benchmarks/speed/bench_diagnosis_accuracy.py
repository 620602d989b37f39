"""The diagnosis's measured accuracy on planted effects, timed: ``accuracy.run_accuracy`` on the headline plan.

Not a CI test: 200 cases take about 15-30 min with one process per core on a 2-core machine.
``HYSBENCH_ACCURACY_CASES`` sets the number of cases (default 200). The plan's rows go to a temporary row file
and its report to a temporary folder (the committed results/ are written by ``hysbench accuracy run``).
"""

import os

from hysbench.benchmarks.diagnosis_accuracy.accuracy import HEADLINE_SEED, run_accuracy


def test_diagnosis_accuracy(benchmark, tmp_path):
    n = int(os.environ.get("HYSBENCH_ACCURACY_CASES", "200"))
    summary = benchmark.pedantic(run_accuracy, args=(n, HEADLINE_SEED, tmp_path / "rows.jsonl.gz",
                                                     tmp_path / "diagnosis_accuracy.md"),
                                 kwargs={"jobs": os.cpu_count() or 1}, rounds=1, iterations=1)
    print(f"\nverdict right {100 * summary['right_share']:.1f} % of {summary['cases']} cases; "
          f"confirmed causes on nulls {summary['confirmed_on_nulls']}; parameters within 25 % "
          f"{100 * summary['parameters_within_share']:.1f} %")
    assert summary["cases"] == n
