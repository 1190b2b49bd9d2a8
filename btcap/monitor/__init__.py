"""The live web monitor of a team: trees with live node states, who runs what, auctions
and why, membership; recordings of the same and their replay."""

from btcap.monitor.monitor import Monitor
from btcap.monitor.record import RecordError, read_record
from btcap.monitor.replay import Replay
from btcap.monitor.view import TeamView

__all__ = ["Monitor", "RecordError", "Replay", "TeamView", "read_record"]
