"""An error on the executor, told at the origin: a :class:`~btcap.bt.state.NodeErrorWarning`.

When an implementation raises on another robot, that robot logs and warns in its own
process; the robot whose mission tree holds the capability only saw it fail, with no
word of why, and the person running the mission watches the origin. So the executor's
report says which node raised what (``ExecutionStatus.detail``), and the origin tells
it: a log line every time (``mission.remote_error``, logger ``btcap``) and, the first
time for each capability node of a tree, the warning a node's own error gives, quietened
by the same filter (``warnings.filterwarnings("ignore", category=btcap.NodeErrorWarning)``).
"""

from __future__ import annotations

from btcap.bt.state import NodeErrorWarning
from btcap.team.capabilities.unassignable import Told, tell_once
from btcap.transports.log import get_logger

__all__ = ["tell_remote_error"]

log = get_logger(__name__)


def tell_remote_error(node: Told, interface: str, robot: str, detail: str) -> None:
    """``node``'s run on ``robot`` ended in ERROR, for the reason ``detail`` (its words)."""
    why = detail or "its implementation ended in ERROR (it gave no reason)"
    log.error("mission.remote_error", capability=node.path, robot=robot, detail=why)
    message = (
        f"capability {node.path!r} ({interface}) ran on robot {robot!r}, where {why}; it "
        "FAILED here, and its parent decides what follows. Fix the implementation on "
        f"{robot} (that robot's log, logger 'btcap', has the traceback), or have it report "
        "a failure it expects as one (return FAILED); later errors of this capability go "
        "to the log only (logger 'btcap')"
    )
    tell_once(node, "remote error", message, NodeErrorWarning)
