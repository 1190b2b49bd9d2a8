"""Reproducible benchmarks and probes: each writes ``bench/results/NAME.json`` and prints
a table; ``python -m btcap.bench NAME`` runs one (:mod:`btcap.bench.__main__` lists them).

By kind: :mod:`~btcap.bench.speed` (each figure beside a peer or floor of the same run),
:mod:`~btcap.bench.allocation` (against scipy's optimum and the mission time's lower
bound), :mod:`~btcap.bench.ros` (against rclpy's and actionlib's own clients) and
:mod:`~btcap.bench.attacks` (PASS/FAIL probes); :mod:`~btcap.bench.common` and
:mod:`~btcap.bench.cpumeter` are what they all measure with."""
