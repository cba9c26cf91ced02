"""The benchmarks of RESULTS.md and BENCHMARKS.md, by name: ``python -m benchmarks list`` (see :mod:`benchmarks.registry`)."""
