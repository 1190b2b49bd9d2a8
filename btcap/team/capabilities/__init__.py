"""The capability model: interfaces, bridges, the Capability node, implementations and
their runs, capability files, the remote slot and the origin's execution handles.
"""
