"""Attack probes: hostile input, bad decodes, insider members, node actions and roles; each
check a PASS/FAIL verdict on counts, never on speed."""
