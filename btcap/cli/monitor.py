"""``btcap replay FILE``: a recording on the monitor's page; ``--monitor`` parsing."""

from __future__ import annotations

import argparse
import contextlib
import sys
from collections.abc import AsyncIterator, Awaitable, Callable, Mapping
from pathlib import Path
from typing import TYPE_CHECKING, TypeVar

from btcap.cli import CliError

if TYPE_CHECKING:  # imported when a monitor is asked for: --help and agents stay fast
    from btcap.monitor.foxlive import FoxgloveLive
    from btcap.monitor.monitor import Monitor
    from btcap.monitor.replay import Replay

__all__ = [
    "DEFAULT_PORT",
    "add_monitor_option",
    "add_parser",
    "monitored",
    "parse_address",
    "serving",
]

DEFAULT_PORT = 8765

T = TypeVar("T")


def parse_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` (``[::1]:PORT`` for IPv6) as (host, port); host defaults to
    loopback. Refused with a message naming the value."""
    host, _, port = text.rpartition(":")
    host = host.strip("[]") or "127.0.0.1"
    try:
        number = int(port)
    except ValueError:
        number = -1
    if not 0 <= number <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r}: expected [HOST:]PORT, a port 0-65535")
    return host, number


def add_monitor_option(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--monitor",
        type=parse_address,
        metavar="[HOST:]PORT",
        help="serve the live monitor page (loopback unless HOST is given; 0: a free port)",
    )
    p.add_argument(
        "--foxglove",
        type=parse_address,
        metavar="[HOST:]PORT",
        help="serve the monitor's channels to Foxglove or Lichtblick over the Foxglove "
        "WebSocket protocol (loopback unless HOST is given; 0: a free port)",
    )


#: Said when the Foxglove SDK cannot be imported (a broken install: btcap depends on it).
_NO_SDK = ("--foxglove and MCAP recordings need the Foxglove SDK, a dependency of btcap: "
           "pip install 'foxglove-sdk>=0.30,<0.31' ({})")  # fmt: skip


@contextlib.asynccontextmanager
async def serving(
    address: tuple[str, int] | None,
    title: str,
    record: Path | None = None,
    metadata: Mapping[str, str] | None = None,
    *,
    foxglove: tuple[str, int] | None = None,
) -> AsyncIterator[Monitor | None]:
    """A started monitor serving ``address`` and/or recording to ``record`` (MCAP if it
    ends ``.mcap``, with ``metadata``) and/or serving Foxglove on ``foxglove`` for the
    block (none of them: None, no monitor at all); prints where each is served."""
    if address is None and record is None and foxglove is None:
        yield None
        return
    from btcap.monitor.monitor import Monitor

    host, port = address if address is not None else ("127.0.0.1", None)
    try:
        monitor = Monitor(
            host=host, port=port, record=record, title=title, metadata=metadata, foxglove=foxglove
        )
        await monitor.start()
    except ImportError as exc:
        raise CliError(_NO_SDK.format(exc)) from None
    except (OSError, RuntimeError) as exc:  # an address in use: the message names it
        raise CliError(str(exc)) from None
    try:
        if address is not None:
            print(f"monitor: {monitor.url}", flush=True)
        if foxglove is not None:
            fhost = f"[{foxglove[0]}]" if ":" in foxglove[0] else foxglove[0]
            print(f"foxglove: ws://{fhost}:{monitor.live.port}", flush=True)
        yield monitor
    finally:
        await monitor.stop()


async def monitored(
    address: tuple[str, int] | None,
    record: Path | None,
    title: str,
    run: Callable[[Monitor | None], Awaitable[T]],
    metadata: Mapping[str, str] | None = None,
    *,
    foxglove: tuple[str, int] | None = None,
) -> T:
    """``run(monitor)`` inside :func:`serving`."""
    async with serving(address, title, record, metadata, foxglove=foxglove) as monitor:
        return await run(monitor)


def add_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "replay",
        help="replay a recorded run on the monitor page",
        description="Serve a recording (btcap run writes monitor.jsonl into its output "
        "folder; --record FILE elsewhere) on the monitor page, with play, pause and seek.",
    )
    p.add_argument("file", type=Path, metavar="FILE", help="a recording (JSON Lines or MCAP)")
    p.add_argument(
        "--monitor",
        type=parse_address,
        default=("127.0.0.1", DEFAULT_PORT),
        metavar="[HOST:]PORT",
        help=f"where to serve the page (default 127.0.0.1:{DEFAULT_PORT})",
    )
    p.add_argument(
        "--foxglove",
        type=parse_address,
        metavar="[HOST:]PORT",
        help="also play it to Foxglove over its WebSocket protocol, as it plays on the page "
        "(loopback unless a host is given)",
    )
    p.add_argument("--speed", type=float, help="clock seconds per wall second")
    p.add_argument("--paused", action="store_true", help="start paused at the beginning")
    p.add_argument(
        "--plot",
        type=Path,
        metavar="PNG",
        help="instead of serving, draw the recording's timeline (a lane per robot) to PNG",
    )
    p.add_argument(
        "--to-mcap",
        type=Path,
        metavar="MCAP",
        help="instead of serving, write the recording as MCAP for Foxglove (docs/foxglove.md)",
    )
    p.set_defaults(handler=replay_command)


def replay_command(args: argparse.Namespace) -> int:
    import asyncio

    from btcap.monitor.record import RecordError
    from btcap.monitor.replay import Replay

    try:
        replay = Replay.open(args.file, speed=args.speed)
    except (RecordError, ValueError) as exc:
        raise CliError(str(exc)) from None
    if replay.cut is not None:  # a killed run's file: what was read, said before anything
        print(f"btcap: warning: {replay.cut}", file=sys.stderr, flush=True)
    if args.to_mcap is not None:
        return _to_mcap(args.file, replay.events, args.to_mcap)
    if args.plot is not None:
        from btcap.monitor.plot import plot_record  # matplotlib only for a plot

        try:
            print(f"wrote {plot_record(replay.events, args.plot, title=replay.title)}")
        except OSError as exc:
            raise CliError(f"--plot {args.plot}: {exc.strerror or exc}") from None
        return 0
    replay.playing = not args.paused
    host, port = args.monitor
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(_serve(replay, host, port, args.foxglove))
    return 0


def _to_mcap(source: Path, events: list[dict[str, object]], out: Path) -> int:
    """The events as an MCAP recording of the same run would hold them (same bytes)."""
    from btcap.monitor.mcaprecord import McapRecorder
    from btcap.monitor.record import RecordError, read_metadata

    try:
        meta = read_metadata(source)
        recorder = McapRecorder(out, meta)
    except (RecordError, OSError) as exc:
        raise CliError(f"--to-mcap {out}: {getattr(exc, 'strerror', None) or exc}") from None
    try:
        recorder.write(events)
    finally:
        recorder.close()
    print(f"wrote {out} ({len(events)} events)")
    return 0


async def _serve(
    replay: Replay, host: str, port: int, foxglove: tuple[str, int] | None = None
) -> None:
    import asyncio

    from btcap.monitor.server import MonitorServer  # aiohttp: only when serving

    live = _foxglove(foxglove) if foxglove is not None else None
    if live is not None:
        replay.add_sink(live.write)
    server = MonitorServer(replay, host, port)
    try:
        await server.start()
    except OSError as exc:
        if live is not None:
            live.close()
        raise CliError(str(exc)) from None
    print(f"replaying {replay.title} ({replay.end - replay.start:.0f} s) on {server.url}")
    if live is not None and foxglove is not None:
        fhost = f"[{foxglove[0]}]" if ":" in foxglove[0] else foxglove[0]
        print(f"foxglove: ws://{fhost}:{live.port}")
    print("press Ctrl-C to stop", flush=True)
    try:
        async with replay:
            await asyncio.Event().wait()
    finally:
        await server.stop()
        if live is not None:
            live.close()


def _foxglove(address: tuple[str, int]) -> FoxgloveLive:
    """The Foxglove server a replay plays to (in the event loop), or one clear line."""
    from btcap.monitor.net import is_loopback
    from btcap.transports.log import get_logger

    try:
        from btcap.monitor.foxlive import FoxgloveLive
    except ImportError as exc:
        raise CliError(_NO_SDK.format(exc)) from None
    if not is_loopback(address[0]):
        log = get_logger(__name__)
        log.warning("monitor.public", host=address[0], note="Foxglove: anyone sees the team")
    try:
        return FoxgloveLive(*address)
    except OSError as exc:  # it names the address
        raise CliError(f"--foxglove: {exc}") from None
