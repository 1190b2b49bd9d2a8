"""What one deterministic simulation test runs, as data: the team, the mission and the
fault schedule, all drawn from one seed (:func:`plan_for`), saved and loaded as JSON.

The fault schedule is a list of :class:`Fault` events on the virtual clock; shrinking a
failure (:mod:`btcap.sim.faults.shrink`) removes events while the failure persists, so the
events are independent of each other: a ``thaw`` without its ``freeze`` does nothing.
"""

from __future__ import annotations

import random
from pathlib import Path

import msgspec

__all__ = [
    "CAPABILITIES",
    "FAULT_KINDS",
    "ORIGIN",
    "STRATEGIES",
    "Fault",
    "Plan",
    "Skill",
    "TaskSpec",
    "load_plan",
    "plan_for",
    "save_plan",
]

#: The registered strategies the test picks from.
STRATEGIES = ("auction", "sequential", "optimal", "consensus", "arrival")
#: The capabilities robots offer (same shape: a task name in, the runner out).
CAPABILITIES = ("Work", "Scan")
#: Fault kinds a seed draws (``mirror`` is test-only: it breaks the network's contract).
FAULT_KINDS = (
    "net",
    "partition",
    "oneway",
    "heal",
    "freeze",
    "thaw",
    "crash",
    "restart",
    "leave",
    "join",
    "mirror",
)
ORIGIN = "op"


class Fault(msgspec.Struct, frozen=True, omit_defaults=True):
    """One event: at clock second ``at``, do ``kind`` to ``robots`` (see FAULT_KINDS).

    ``net`` sets the message faults from then on (``rates``: drop, duplicate, delay
    chances and the longest delay in seconds); ``partition`` splits the team into
    ``groups``; ``oneway`` drops what ``robots[0]`` sends ``robots[1]`` (not the other
    way); ``heal`` ends partitions and one-way cuts; ``mirror`` also delivers every
    execution message meant for another robot to ``robots[0]`` and loses the statuses it
    sends (a network that forges deliveries: only for testing the checks).
    """

    at: float
    kind: str
    robots: tuple[str, ...] = ()
    groups: tuple[tuple[str, ...], ...] = ()
    rates: tuple[float, ...] = ()

    def line(self) -> str:
        what = self.kind
        if self.robots:
            what += " " + ",".join(self.robots)
        if self.groups:
            what += " " + " | ".join(",".join(g) for g in self.groups)
        if self.rates:
            drop, dup, delay, most = self.rates
            what += f" drop={drop:.2f} dup={dup:.2f} delay={delay:.2f}<={most:.2f}s"
        return f"{self.at:8.3f}  {what}"


class Skill(msgspec.Struct, frozen=True):
    capability: str
    cost: float


class TaskSpec(msgspec.Struct, frozen=True):
    name: str
    capability: str
    duration_s: float


class Plan(msgspec.Struct, frozen=True, kw_only=True):
    """A whole run: replaying the same plan gives the same trace."""

    seed: int
    strategy: str
    #: Every robot that ever lives, with its skills (the origin too, if it has any).
    robots: dict[str, tuple[Skill, ...]]
    initial: tuple[str, ...]  #: the robots there from the start (the others join)
    sequence: bool  #: the tasks one after the other, else in parallel
    tasks: tuple[TaskSpec, ...]
    faults: tuple[Fault, ...]
    heal_at: float  #: every fault ends here: healed, thawed, restarted, clean links
    quiet_s: float  #: the mission must be done this long after ``heal_at``
    #: A second mission, held by the first robot (never crashed nor leaving): two
    #: origins compete for the same robots.
    second: tuple[TaskSpec, ...] = ()

    def with_faults(self, faults: tuple[Fault, ...]) -> Plan:
        return msgspec.structs.replace(self, faults=faults)


def plan_for(
    seed: int, *, robots: tuple[int, int] = (3, 5), inject: bool = False, heavy: bool = False
) -> Plan:
    """The plan of ``seed``: a team of ``robots`` (a range) plus the origin, 2-4 tasks and
    1-6 faults in the first 4-12 clock seconds. ``heavy``: 4-14 faults over 8-24 s, one-way
    link cuts among them, loss up to 40 %, and half the time the origin offers a capability
    too, half the time a second mission on the first robot. ``inject`` adds a ``mirror``
    fault."""
    rng = random.Random(seed)
    n = rng.randint(*robots)
    names = [f"r{i}" for i in range(1, n + 1)]
    spare = [f"j{i}" for i in range(1, rng.randint(0, 2) + 1)]
    skills: dict[str, tuple[Skill, ...]] = {}
    for i, robot in enumerate(names + spare):
        caps = [c for c in CAPABILITIES if rng.random() < 0.6] or [CAPABILITIES[i % 2]]
        skills[robot] = tuple(Skill(c, round(rng.uniform(1.0, 10.0), 2)) for c in caps)
    for cap in CAPABILITIES:  # every capability has someone from the start
        if not any(cap in _caps(skills[r]) for r in names):
            robot = names[rng.randrange(n)]
            skills[robot] += (Skill(cap, round(rng.uniform(1.0, 10.0), 2)),)
    tasks = tuple(
        TaskSpec(f"t{k}", rng.choice(CAPABILITIES), round(rng.uniform(0.5, 4.0), 2))
        for k in range(1, rng.randint(2, 4) + 1)
    )
    heal_at = round(rng.uniform(8.0, 24.0) if heavy else rng.uniform(4.0, 12.0), 3)
    two = heavy and rng.random() < 0.5
    faults = _faults(rng, names, spare, heal_at, heavy, keep=names[0] if two else "")
    second = tuple(
        TaskSpec(f"u{k}", rng.choice(CAPABILITIES), round(rng.uniform(0.5, 4.0), 2))
        for k in range(1, (rng.randint(1, 3) if two else 0) + 1)
    )
    if heavy and rng.random() < 0.5:  # the origin works too: its own runs, self-awards
        skills[ORIGIN] = (Skill(rng.choice(CAPABILITIES), round(rng.uniform(1.0, 10.0), 2)),)
    if inject:
        pick = random.Random(f"inject {seed}")  # the plan's other draws stay the same
        faults.append(Fault(0.0, "mirror", (pick.choice(names),)))
    return Plan(
        seed=seed,
        strategy=rng.choice(STRATEGIES),
        robots=skills,
        initial=tuple(names),
        sequence=rng.random() < 0.4,
        tasks=tasks,
        faults=tuple(sorted(faults, key=lambda f: f.at)),
        heal_at=heal_at,
        quiet_s=45.0,
        second=second,
    )


def _caps(skills: tuple[Skill, ...]) -> set[str]:
    return {s.capability for s in skills}


def _faults(
    rng: random.Random,
    names: list[str],
    spare: list[str],
    heal_at: float,
    heavy: bool,
    keep: str = "",
) -> list[Fault]:
    """The faults of a plan; ``keep`` (a robot holding a mission) is partitioned and
    frozen but never crashed nor leaving."""
    out: list[Fault] = []
    everyone = [ORIGIN, *names]
    kinds = ("net", "net", "partition", "freeze", "crash", "leave")

    def when(after: float = 0.2) -> float:
        return round(rng.uniform(after, heal_at), 3)

    for _ in range(rng.randint(4, 14) if heavy else rng.randint(1, 6)):
        kind = rng.choice((*kinds, "oneway", "oneway") if heavy else kinds)
        t = when()
        if kind == "oneway":
            a, b = rng.sample(everyone, 2)
            out.append(Fault(t, "oneway", (a, b)))
            out.append(Fault(when(t), "heal"))
        elif kind == "net":
            rates = (
                round(rng.uniform(0.0, 0.4 if heavy else 0.25), 3),
                round(rng.uniform(0.0, 0.2), 3),
                round(rng.uniform(0.0, 0.5), 3),
                round(rng.uniform(0.01, 0.6), 3),
            )
            out.append(Fault(t, "net", rates=rates))
        elif kind == "partition":
            cut = rng.sample(everyone, rng.randint(1, len(everyone) - 1))
            rest = [r for r in everyone if r not in cut]
            out.append(Fault(t, "partition", groups=(tuple(sorted(cut)), tuple(rest))))
            out.append(Fault(when(t), "heal"))
        else:
            robot = rng.choice([n for n in names if n != keep] if kind != "freeze" else names)
            back = {"freeze": "thaw", "crash": "restart", "leave": "join"}[kind]
            out.append(Fault(t, kind, (robot,)))
            if rng.random() < 0.7:
                out.append(Fault(when(t), back, (robot,)))
    for robot in spare:  # newcomers
        t = when()
        out.append(Fault(t, "join", (robot,)))
        if rng.random() < 0.3:
            out.append(Fault(when(t), "leave", (robot,)))
    return out


def save_plan(plan: Plan, path: Path) -> None:
    path.write_bytes(msgspec.json.format(msgspec.json.encode(plan)) + b"\n")


def load_plan(path: Path) -> Plan:
    """A plan from a JSON file; ValueError naming the file and what is wrong."""
    try:
        plan = msgspec.json.decode(path.read_bytes(), type=Plan)
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror}") from None
    except msgspec.DecodeError as exc:
        raise ValueError(f"{path}: not a sim-test plan: {exc}") from None
    bad = [f.kind for f in plan.faults if f.kind not in FAULT_KINDS]
    if bad:
        raise ValueError(f"{path}: unknown fault kind {bad[0]!r}, expected one of {FAULT_KINDS}")
    if plan.strategy not in STRATEGIES:
        raise ValueError(f"{path}: strategy {plan.strategy!r}, expected one of {STRATEGIES}")
    return plan
