"""``btcap keys new NAME --role ROLE --dir DIR``: a member's CURVE key pair in ZeroMQ's
certificate format, its role in the metadata.

Give ``NAME.key_secret`` to robot NAME only; copy ``NAME.key`` into the team's directory
of public certificates (the allow-list every member's transport loads as ``trusted``).
The role (robot, operator, observer) says what the member may send
(:mod:`btcap.team.membership.roles`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from btcap.cli import CliError

#: btcap.transports.identity.ROLES, spelt out: ``--help`` loads no transport module.
ROLES = ("robot", "operator", "observer")

__all__ = ["add_parser"]


def add_parser(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add ``btcap keys`` and ``btcap keys new``."""
    keys = subparsers.add_parser(
        "keys", help="make CURVE keys for a team", description="Make CURVE keys for a team."
    )
    keys.set_defaults(handler=lambda args: _help(keys))
    cmds = keys.add_subparsers(dest="keys_command", metavar="SUBCOMMAND")
    p = cmds.add_parser(
        "new",
        help="write NAME.key (public) and NAME.key_secret (secret) with a role; never overwrites",
        description="Write a member's CURVE key pair in ZeroMQ's certificate format: "
        "NAME.key (public) and NAME.key_secret (secret), into DIR, the role in their "
        "metadata; an existing file is never overwritten. Give NAME.key_secret to NAME only; "
        "copy NAME.key into the team's directory of public certificates (the allow-list "
        "every member's transport loads as 'trusted'). Roles: a robot sends anything (it "
        "bids, runs and reports work); an operator runs missions and asks, but never bids "
        "or runs work; an observer only asks (btcap team status).",
    )
    p.add_argument("name", metavar="NAME", help="the member's name (its system id)")
    p.add_argument(
        "--role",
        required=True,
        choices=ROLES,
        help="what the member may do: robot, operator or observer",
    )
    p.add_argument("--dir", type=Path, default=Path("."), help="where to write (default: .)")
    p.set_defaults(handler=_new)


def _help(parser: argparse.ArgumentParser) -> int:
    parser.print_help(sys.stderr)
    return 2


def _new(args: argparse.Namespace) -> int:
    from btcap.transports.security import write_key_pair  # pyzmq: only when run

    try:
        public, secret = write_key_pair(args.dir, args.name, args.role)
    except (ValueError, OSError) as exc:
        raise CliError(str(exc)) from None
    print(f"wrote {public} (public, role {args.role}: share it with the team)")
    print(f"wrote {secret} (secret: keep it on {args.name} only)")
    return 0
