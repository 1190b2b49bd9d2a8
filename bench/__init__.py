"""Reproducible benchmarks: each writes ``bench/results/NAME.json`` and prints a table."""
