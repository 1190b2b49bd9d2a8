"""``btcap schema``'s parser, apart from :mod:`btcap.sim.running.reference` (which imports every
file type) so that ``btcap --help`` stays fast."""

from __future__ import annotations

import argparse

__all__ = ["KINDS", "add_parser"]

#: The kinds of file with a schema (``btcap.sim.running.reference.FORMATS``; a test keeps
#: them equal).
KINDS = ("scenario", "agent", "team")


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "schema",
        help="print the JSON Schema of scenario, agent or team files",
        description="Print the JSON Schema of a kind of file, for editors (the YAML "
        "language server: '# yaml-language-server: $schema=PATH' as a file's first line) "
        "and validators. Every field is described in docs/files.md.",
    )
    p.add_argument("kind", choices=KINDS, help="which kind of file")
    what = p.add_mutually_exclusive_group()
    what.add_argument(
        "--path", action="store_true", help="print where the schema shipped with btcap is"
    )
    what.add_argument(
        "--markdown", action="store_true", help="print the reference of every field instead"
    )
    p.set_defaults(handler=_schema)


def _schema(args: argparse.Namespace) -> int:
    from btcap.sim.running.reference import schema_command

    return schema_command(args)
