"""A mkdocs hook: the CLI reference page is the ``--help`` of every ``btcap`` command,
taken from the parser at build time so it cannot fall behind the code."""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import os
from collections.abc import Iterator
from typing import Any

MARKER = "<!-- btcap-cli-reference -->"
#: A warning here fails the strict build, as mkdocs' own would.
log = logging.getLogger("mkdocs.plugins.btcap_cli_reference")


def _commands(
    parser: argparse.ArgumentParser, name: str
) -> Iterator[tuple[str, argparse.ArgumentParser]]:
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, subparser in action.choices.items():
                yield from _commands(subparser, f"{name} {sub}")


def reference() -> str:
    """Markdown: a section with the help text of each command, in the parser's order."""
    from btcap.cli import build_parser

    saved = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = "90"  # argparse wraps to the terminal: pin it for the page
    try:
        complaints = io.StringIO()
        with contextlib.redirect_stderr(complaints):  # a command plugin that did not load
            root = build_parser()
        for line in complaints.getvalue().splitlines():
            log.warning("CLI reference incomplete: %s", line)
        parts = []
        for name, parser in _commands(root, "btcap"):
            parser.prog = name
            parts.append(f"## `{name}`\n\n```text\n{parser.format_help().rstrip()}\n```\n")
        return "\n".join(parts)
    finally:
        if saved is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = saved


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, reference())
