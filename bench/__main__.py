"""``python -m btcap.bench NAME [--quick]``: run one benchmark (or ``all``) and write its JSON."""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence

#: Each benchmark's name on the command line and the module that runs it.
BENCHES = {
    "tick": "speed.tick",
    "script": "speed.script",
    "transport": "speed.transport",
    "auction": "speed.auction",
    "sim": "speed.sim",
    "allocation": "allocation.optimum",
    "membership": "allocation.membership",
    "monitor": "speed.monitor",
    "recording": "speed.recording",
    "btlog": "speed.btlog",
    "attacks": "attacks.probe",
    "missiontime": "allocation.missiontime",
    "mission_step": "speed.mission_step",
    "missionbound": "allocation.missionbound",
    "strategytime": "allocation.strategytime",
}
#: Benchmarks that need what `make venv` does not install, left out of ``all``: ``ros``
#: needs ROS 2 and a private network namespace (`make bench-ros`), ``ros1`` Debian's rospy
#: (`make bench-ros1`).
OPTIONAL = {"ros": "ros.ros2", "ros1": "ros.ros1"}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m btcap.bench", description=__doc__)
    parser.add_argument("name", choices=(*BENCHES, *OPTIONAL, "all"), help="which benchmark to run")
    parser.add_argument("--quick", action="store_true", help="fewer repeats, for CI smoke runs")
    args, rest = parser.parse_known_args(argv)
    names = tuple(BENCHES) if args.name == "all" else (args.name,)
    own = ("allocation", "missiontime", "missionbound", "recording", "strategytime")
    if rest and (len(names) != 1 or names[0] not in own):  # only these take options of their own
        parser.error(f"unrecognized arguments: {' '.join(rest)}")
    failed = False
    for name in names:
        module = importlib.import_module(f"btcap.bench.{(BENCHES | OPTIONAL)[name]}")
        if rest:  # ``allocation --seeds 1000-1019 --map cave:7``, ``missiontime --robots 5``
            module.main(rest, quick=args.quick)
            continue
        # A probe (``attacks``) returns False when a check failed; benchmarks return None.
        failed |= module.run(quick=args.quick) is False
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
