"""Who is in the team and what each member can do: the membership and capability
repository actors (the repository is gossiped through membership).
"""
