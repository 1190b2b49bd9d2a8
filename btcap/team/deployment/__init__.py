"""Running robots from files and processes: agent files, agent specs, spawning,
launching and deploying agents, and leaving when the supervisor's pipe closes.
"""
