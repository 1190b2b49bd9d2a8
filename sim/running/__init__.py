"""Running and recording a scenario: ``btcap run``'s runner, the hosts robots live in (this
process, one process each), metrics, plots, sweeps, the world's monitor feed, and the
file schemas."""
