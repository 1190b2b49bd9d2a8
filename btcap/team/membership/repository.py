"""The capability repository: what this robot can do, and what every teammate can do."""

from __future__ import annotations

from collections.abc import Callable, Iterable

from btcap.actors import Actor, Supervision, handler
from btcap.bt.state import TreeError
from btcap.team.capabilities.capability import CapabilityInterface
from btcap.team.capabilities.implementation import Implementation
from btcap.team.core.bounds import Budgets
from btcap.team.membership.membership import Membership, TeamEvent
from btcap.team.messages import RepositoryQuery, RepositoryState
from btcap.transports import Address
from btcap.transports.log import get_logger, worth_logging

__all__ = ["MAX_STATE_COST", "MAX_TEAM_COST", "CapabilityRepository", "state_cost"]

log = get_logger(__name__)

#: What one teammate's capabilities may cost to hold (about bytes; see
#: :func:`state_cost`): hundreds of interfaces with long port lists fit.
MAX_STATE_COST = 256 * 1024
#: What the whole team's may cost together: a flood of made-up members (without keys,
#: anyone may join) cannot take more memory than this.
MAX_TEAM_COST = 32 * 1024 * 1024
#: Repository queries answered per teammate at once, then per clock second (one comes
#: with each join and each change of its capabilities).
QUERIES_BURST = 16.0
QUERIES_PER_S = 4.0
#: The per-entry overhead counted (a dict slot and two str objects, roughly).
_ENTRY = 128


def state_cost(state: RepositoryState) -> int:
    """About the bytes holding ``state`` takes."""
    interfaces = sum(len(k) + len(v) + _ENTRY for k, v in state.interfaces.items())
    return _ENTRY + interfaces + sum(len(c) + _ENTRY // 2 for c in state.succeeded)


class CapabilityRepository(Actor):
    """Local interfaces and implementations (changeable at run time), plus a team-wide view.

    Changes are broadcast to the team at once; a newcomer gets the full state directly,
    and a heartbeat announcing an unknown version triggers a query, so views converge
    even when an update was lost.
    """

    PATH = "repository"
    #: Input from peers must never stop it (a bug shows as a logged failure, not silence).
    supervision = Supervision.RESUME

    def __init__(self, robot: str, *, team: Membership | None = None) -> None:
        """``team`` is the robot's membership, followed while the repository runs (None:
        no team, e.g. a repository used alone)."""
        super().__init__()
        self.robot = robot
        self.version = 0
        self.interfaces: dict[str, CapabilityInterface] = {}
        self.implementations: dict[str, list[Implementation]] = {}
        self.succeeded: set[str] = set()
        self.team: dict[str, RepositoryState] = {}
        self._unsubscribe: Callable[[], None] | None = None
        self._team = team
        self.refused = 0  #: states sent in another robot's name
        self.early = 0  #: states from robots not (yet) members, dropped
        self.oversized = 0  #: states over MAX_STATE_COST, or over MAX_TEAM_COST in all
        self.max_state_cost = MAX_STATE_COST
        self.max_team_cost = MAX_TEAM_COST
        self._costs: dict[str, int] = {}  #: what each teammate's state held costs
        self._held = 0  #: their sum
        #: Queries answered per teammate (each answer is this robot's whole state).
        self.queries = Budgets(QUERIES_PER_S, QUERIES_BURST)
        self._listeners: list[Callable[[str], None]] = []

    # -- local content ----------------------------------------------------------------
    def add_interface(self, interface: CapabilityInterface) -> None:
        known = self.interfaces.get(interface.name)
        if known is not None and known.identity != interface.identity:
            raise TreeError(
                f"repository of {self.robot}: interface {interface.name!r} is already "
                f"{known.identity}, not {interface.identity}"
            )
        self.interfaces[interface.name] = interface

    def add_implementation(self, impl: Implementation) -> None:
        self.add_interface(impl.interface)
        impls = self.implementations.setdefault(impl.interface.name, [])
        if any(i.name == impl.name for i in impls):
            raise TreeError(f"repository of {self.robot}: implementation {impl.name!r} exists")
        impls.append(impl)
        self._changed()

    def remove_implementation(self, interface: str, name: str) -> None:
        impls = self.implementations.get(interface, [])
        kept = [i for i in impls if i.name != name]
        if len(kept) == len(impls):
            raise TreeError(f"repository of {self.robot}: no implementation {interface}/{name}")
        if kept:
            self.implementations[interface] = kept
        else:
            del self.implementations[interface]
        self._changed()

    def extend(self, impls: Iterable[Implementation]) -> None:
        for impl in impls:
            self.add_implementation(impl)

    def local_implementations(
        self, interface: str, identity: str | None = None
    ) -> list[Implementation]:
        impls = self.implementations.get(interface, [])
        if identity is not None:
            impls = [i for i in impls if i.interface.identity == identity]
        return impls

    def record_success(self, capability: str) -> None:
        """A capability completed on this robot (for preconditions, local and remote)."""
        if capability not in self.succeeded:
            self.succeeded.add(capability)
            self._changed()

    # -- team view --------------------------------------------------------------------
    def subscribe(self, listener: Callable[[str], None]) -> Callable[[], None]:
        """Call ``listener(robot)`` when a teammate's capabilities are first known (a join:
        the membership event comes before its capabilities do)."""
        self._listeners.append(listener)
        return lambda: self._listeners.remove(listener) if listener in self._listeners else None

    def providers(self, identity: str) -> set[str]:
        """Robots (this one included) that implement the interface with this identity."""
        robots = {r for r, st in self.team.items() if identity in st.interfaces.values()}
        if any(
            i.interface.identity == identity
            for impls in self.implementations.values()
            for i in impls
        ):
            robots.add(self.robot)
        return robots

    def succeeded_anywhere(self, capability: str) -> bool:
        return capability in self.succeeded or any(
            capability in st.succeeded for st in self.team.values()
        )

    def state(self) -> RepositoryState:
        return RepositoryState(
            self.robot,
            self.version,
            {name: impls[0].interface.identity for name, impls in self.implementations.items()},
            sorted(self.succeeded),
        )

    def _changed(self) -> None:
        self.version += 1
        if self._system is not None:
            self.system.broadcast(self.PATH, self.state())

    # -- life cycle and messages ------------------------------------------------------
    def on_start(self) -> None:
        if self._team is not None:
            self._unsubscribe = self._team.subscribe(self._on_team)
            self.start_task(self._catch_up(self._team), name=f"repository {self.robot}")

    async def _catch_up(self, team: Membership) -> None:
        """Ask again, every failure timeout, members whose state we lack or whose
        heartbeats name a newer version: a lost query or reply is otherwise never
        repeated (the version it answers does not change), and the member's capabilities
        stay unknown for good (found by ``btcap sim-test``, seed 879)."""
        clock = self.system.clock
        while True:
            await clock.sleep(team.failure_timeout_s)
            for robot, member in team.members.items():
                known = self.team.get(robot)
                if known is None or known.version < member.repo_version:
                    self.system.ref(f"{robot}/{self.PATH}").tell(RepositoryQuery(self.robot))

    def on_stop(self) -> None:
        if self._unsubscribe is not None:
            self._unsubscribe()
            self._unsubscribe = None

    def _on_team(self, event: TeamEvent, robot: str) -> None:
        system = self.system
        if event is TeamEvent.JOINED:
            system.ref(f"{robot}/{self.PATH}").tell(self.state())
            if robot not in self.team:
                system.ref(f"{robot}/{self.PATH}").tell(RepositoryQuery(self.robot))
        elif event is TeamEvent.CHANGED:
            system.ref(f"{robot}/{self.PATH}").tell(RepositoryQuery(self.robot))
        elif event in (TeamEvent.LEFT, TeamEvent.FAILED):
            self.team.pop(robot, None)
            self._held -= self._costs.pop(robot, 0)

    @handler
    def on_state(self, msg: RepositoryState) -> None:
        sender = self.sender
        if msg.robot != sender or sender == self.robot:
            # Each robot speaks for itself only.
            self.refused += 1
            if worth_logging(self.refused):
                log.warning(
                    "repository.refused",
                    robot=self.robot,
                    sender=sender,
                    claims=msg.robot[:64],
                    count=self.refused,
                )
            return
        if sender not in self._alive():
            # Not (yet) a member: nothing is held for it. A joining robot's state often
            # overtakes its first heartbeat; the join then asks for it again.
            self.early += 1
            log.debug("repository.not_a_member", robot=self.robot, sender=sender)
            return
        known = self.team.get(msg.robot)
        if known is not None and msg.version < known.version:
            return
        if (why := self._over(sender, msg)) is not None:
            self.oversized += 1
            if worth_logging(self.oversized):
                log.warning(
                    "repository.oversized",
                    robot=self.robot,
                    sender=sender,
                    why=why,
                    count=self.oversized,
                )
            return
        self.team[msg.robot] = msg
        if known is None:
            for listener in list(self._listeners):
                try:
                    listener(msg.robot)
                except Exception as exc:
                    log.error("repository.listener_failed", robot=self.robot, exc_info=exc)

    def _over(self, sender: str, msg: RepositoryState) -> str | None:
        """Why ``msg`` is too big to hold, or None (then its cost is counted as held)."""
        cost = state_cost(msg)
        if cost > self.max_state_cost:
            return f"capabilities cost {cost}, over {self.max_state_cost}"
        held = self._held - self._costs.get(sender, 0) + cost
        if held > self.max_team_cost:
            return f"the team's capabilities would cost {held}, over {self.max_team_cost}"
        self._costs[sender], self._held = cost, held
        return None

    @handler
    def on_query(self, msg: RepositoryQuery) -> None:
        sender = self.sender  # answered to who asked, whatever name the query carries
        member = sender != self.robot and sender in self._alive()
        if member and self.queries.allow(sender, self.system.clock.now()):
            self.system.ref(Address(sender, self.PATH)).tell(self.state())

    def _alive(self) -> frozenset[str]:
        return self._team.alive() if self._team is not None else frozenset()
