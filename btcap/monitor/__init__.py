"""The live web monitor of a team: trees with live node states, who runs what, auctions
and why, membership; recordings of the same and their replay."""

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from btcap.monitor.monitor import Monitor
    from btcap.monitor.record import RecordError, read_record
    from btcap.monitor.replay import Replay
    from btcap.monitor.view import TeamView

#: Imported on first use (see btcap._lazy): ``btcap replay`` and ``--monitor`` parsing
#: need none of the monitor's machinery.
_EXPORTS = {
    "btcap.monitor.monitor": ("Monitor",),
    "btcap.monitor.record": ("RecordError", "read_record"),
    "btcap.monitor.replay": ("Replay",),
    "btcap.monitor.view": ("TeamView",),
}

if not TYPE_CHECKING:
    from btcap._lazy import lazy_exports

    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = ["Monitor", "RecordError", "Replay", "TeamView", "read_record"]
