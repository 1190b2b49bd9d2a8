"""Speed benchmarks, each beside its peer or floor measured in the same run: ticks, scripts,
transport, auctions, the simulator, monitor and recording costs."""
