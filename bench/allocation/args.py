"""Command-line values the allocation benches share: seed ranges and maps."""

from __future__ import annotations

import argparse

from btcap.sim.world.grid import GridMap

__all__ = ["load_map", "seed_list"]


def seed_list(text: str) -> list[int]:
    """``0-19`` or ``3,5,8`` (or both, comma-separated) as a list of seeds."""
    seeds: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.strip().partition("-")
        try:
            more = list(range(int(lo), int(hi) + 1)) if hi else [int(lo)]
        except ValueError:
            more = []
        if not more:  # not numbers, or a range running backwards (5-3)
            raise argparse.ArgumentTypeError(f"--seeds {text!r}: expected seeds like 0-19 or 3,5,8")
        seeds += more
    return seeds


def load_map(text: str) -> GridMap:
    """``cave:SEED`` (an 80x60 generated cave) or a map file (.npy, .png, .txt)."""
    if text.startswith("cave:"):
        try:
            return GridMap.generate_cave(80, 60, seed=int(text[5:]))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"--map {text!r}: expected cave:SEED with an integer seed"
            ) from None
    return GridMap.load(text)
