"""The scenarios shipped with btcap, by name: listed (``btcap run --help``) without
loading the simulation."""

from __future__ import annotations

from pathlib import Path

__all__ = ["SCENARIO_DIR", "builtin_scenarios"]

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"


def builtin_scenarios() -> dict[str, Path]:
    """The scenarios shipped with btcap (the paper's three), by name."""
    return {p.stem: p for p in sorted(SCENARIO_DIR.glob("*.yaml"))}
