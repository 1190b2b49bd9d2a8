"""The "did you mean" hint of a line refusing a misspelt name (a node type, a type name)."""

from __future__ import annotations

import difflib
from collections.abc import Iterable

__all__ = ["did_you_mean"]


def did_you_mean(word: str, options: Iterable[str]) -> str:
    """' (did you mean X, Y?)' for a misspelt name, or '' if nothing is close."""
    near = difflib.get_close_matches(word, list(options), n=3, cutoff=0.6)
    return f" (did you mean {', '.join(near)}?)" if near else ""
