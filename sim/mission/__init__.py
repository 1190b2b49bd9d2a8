"""The paper's find-and-decontaminate mission: its capabilities and each robot's
implementations, the mission trees (the paper's and the pool), scenarios and their files,
and the mission time's lower bound."""
