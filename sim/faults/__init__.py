"""The whole-team fault simulation (``btcap sim-test``): real agents on a seeded faulty
network, fault plans, invariants checked after every step, and shrinking."""
