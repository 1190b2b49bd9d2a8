"""``python -m btcap.bench NAME [--quick]``: run one benchmark (or ``all``) and write its JSON."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence

BENCHES = ("tick", "transport", "auction", "sim", "allocation")


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m btcap.bench", description=__doc__)
    parser.add_argument("name", choices=(*BENCHES, "all"), help="which benchmark to run")
    parser.add_argument("--quick", action="store_true", help="fewer repeats, for CI smoke runs")
    args = parser.parse_args(argv)
    names = BENCHES if args.name == "all" else (args.name,)
    for name in names:
        importlib.import_module(f"btcap.bench.{name}").run(quick=args.quick)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
