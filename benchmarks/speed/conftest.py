"""pytest-benchmark suite (not run by CI): `python -m pytest benchmarks/speed --benchmark-only`."""
