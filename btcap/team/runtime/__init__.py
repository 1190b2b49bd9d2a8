"""One robot's runtime: the Agent, mission control, the origin and executor sides,
moving work (re-evaluation) and the wire protocol's registry.
"""
