"""Allocation benchmarks: per-batch allocation against scipy's optimum, mission time against
its lower bound per strategy, exchanges, joins and membership."""
