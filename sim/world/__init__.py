"""The grid world and its robots: maps, distance fields, robot models, the robots' motion,
and the simulation manager that times their operations and keeps the shared object store."""
