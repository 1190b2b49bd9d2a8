"""Pictures of trees through Graphviz's ``dot``, which btcap does not bundle."""

from __future__ import annotations

import shutil
import subprocess

from btcap.cli import CliError

__all__ = ["PICTURES", "graphviz"]

#: Picture formats ``tree dot`` hands to Graphviz, by output suffix.
PICTURES = {".svg": "svg", ".png": "png", ".pdf": "pdf"}


def graphviz(text: str, fmt: str) -> bytes:
    """DOT ``text`` rendered as ``fmt`` (svg, png, pdf); a CliError says what is missing."""
    dot = shutil.which("dot")
    if dot is None:
        raise CliError(
            f"writing .{fmt} needs Graphviz's 'dot' program, which is not on PATH; install "
            f"Graphviz (e.g. apt install graphviz) or write a .dot file and render it elsewhere"
        )
    try:
        done = subprocess.run(
            [dot, f"-T{fmt}"], input=text.encode(), capture_output=True, timeout=120, check=False
        )
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise CliError(f"Graphviz 'dot' failed: {exc}") from None
    if done.returncode != 0:
        raise CliError(f"Graphviz 'dot' failed: {done.stderr.decode(errors='replace').strip()}")
    return done.stdout
