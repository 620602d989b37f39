"""The top layer: the benchmark matrix, ablation, diagnosis, compensation, reports, figures and the
CLI (``hysbench.benchmarks.cli``)."""

import hysbench.models  # noqa: F401  (first: numba's cache folder, see models/numba_cache.py)
