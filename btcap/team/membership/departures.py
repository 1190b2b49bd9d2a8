"""Who failed or left lately, kept for ``btcap team status`` and said in the log.

The membership forgets a robot the moment it fails or leaves; a person asking later what
happened to it needs the record: which robot, which life (incarnation), failed or left,
when and why. :class:`DepartureLog` keeps the latest few, fed by the membership's
listener events, and answers :class:`~btcap.team.messages.DeparturesQuery` (observers ask it too).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from btcap.actors import Actor, Supervision, handler
from btcap.team.membership.membership import Membership, TeamEvent
from btcap.team.messages import Departed, Departures, DeparturesQuery
from btcap.transports.log import get_logger

__all__ = ["Departure", "DepartureLog"]

log = get_logger(__name__)


@dataclass(frozen=True, slots=True)
class Departure:
    robot: str
    incarnation: int
    how: str  #: "failed" or "left"
    at: float  #: on the robot's clock
    why: str


class DepartureLog(Actor):
    """The latest ``keep`` departures one robot saw (older ones are forgotten).

    ``loud``: a teammate's failure is a warning (what a robot run from the command line
    shows by default), not a debug line (a simulation of many robots in one process).
    """

    PATH = "departures"
    supervision = Supervision.RESUME

    def __init__(self, team: Membership, *, keep: int = 32, loud: bool = False) -> None:
        super().__init__()
        self.team = team
        self.loud = loud
        self.departures: deque[Departure] = deque(maxlen=keep)
        self._lives: dict[str, int] = {}  #: each member's incarnation, from its join
        self._unsubscribe = team.subscribe(self._on_team)

    def on_stop(self) -> None:
        self._unsubscribe()

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        member = self.team.members.get(robot)
        if event is TeamEvent.JOINED and member is not None:
            self._lives[robot] = member.incarnation
            return
        if event not in (TeamEvent.FAILED, TeamEvent.LEFT):
            return
        life = self._lives.pop(robot, 0)
        if event is TeamEvent.LEFT:
            how, why = "left", "said goodbye"
        elif member is not None and member.incarnation != life:
            how, why = "failed", "restarted (a new life under the same name)"
        else:
            how, why = "failed", "stopped answering probes (suspected, not refuted)"
        now = self.system.clock.now() if self._system is not None else 0.0
        self.departures.appendleft(Departure(robot, life, how, now, why))
        emit = (log.warning if how == "failed" else log.info) if self.loud else log.debug
        emit(f"team.member_{how}", robot=self.team.robot, member=robot, why=why)

    @handler
    def on_query(self, msg: DeparturesQuery) -> Departures | None:
        # Anyone the transport let through (with keys: a member or an observer, as
        # for the status desk): who left and when is no secret within the team.
        now = self.system.clock.now()
        told = [
            Departed(d.robot, d.incarnation, d.how, max(0, round(1000 * (now - d.at))), d.why)
            for d in self.departures
        ]
        return Departures(self.team.robot, told)
