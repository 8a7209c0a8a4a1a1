"""Benchmarks (``python -m waterair.bench``); see :mod:`waterair.bench.__main__`."""
