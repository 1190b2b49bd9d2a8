"""Members that never answered us: probed at once, passed on only once they answer,
forgotten quickly once silent; a keyless flood of made-up members beating a while,
then silent, is all forgotten within the stated bound, with no false failure (explicit
time, the library's default timing, the seeded network of :mod:`btcap.sim.faults.swimnet`)."""

from __future__ import annotations

import random

from btcap.sim.faults.swimnet import SwimNet
from btcap.team.core.members import TeamEvent
from btcap.team.core.newcomers import RETRIES_PER_PERIOD
from btcap.team.core.swim import Swim, SwimParams
from btcap.team.messages import Heard, Heartbeat
from btcap.transports.message import Message

DEFAULTS = SwimParams(period_s=0.1, floor_s=0.5)  # the library's defaults


def _probe_of(sends: list[tuple[str, Message]], to: str) -> int:
    [probe] = [m.probe for t, m in sends if t == to and isinstance(m, Heartbeat) and m.probe]
    return probe


def test_a_newcomer_is_probed_at_once_and_passed_on_only_once_it_answers() -> None:
    a = Swim("a", 1, DEFAULTS, random.Random(0))
    step = a.on_heartbeat(Heartbeat("b", 7, 0, probe=3), 0.0)
    assert step.events == [(TeamEvent.JOINED, "b")]
    [(to, hb)] = step.sends  # one message: our answer to its probe, and our own probe
    assert to == "b"
    assert isinstance(hb, Heartbeat)
    assert hb.ack == 3
    nonce = hb.probe
    assert nonce
    assert "b" in a.newcomers
    assert a.rumours.about("b") is None  # nobody is told of it yet
    # What it says of others does not count yet (a liar's suspicion of c, here).
    a.on_heartbeat(Heartbeat("c", 1, 0), 0.0)
    a.on_heartbeat(Heartbeat("b", 7, 0, heard=[Heard("c", 1, 0, 0, True, "b")]), 0.01)
    assert a.members["c"].suspicion is None
    assert not a.on_heartbeat(Heartbeat("b", 7, 0, ack=nonce + 1), 0.02).confirmed
    step = a.on_heartbeat(Heartbeat("b", 7, 0, ack=nonce), 0.02)
    assert step.confirmed == ["b"]  # worth a welcome
    assert "b" not in a.newcomers
    assert a.rumours.about("b") == Heard("b", 7, 0)


def test_a_silent_newcomer_is_asked_again_then_forgotten_a_confirmed_one_is_not() -> None:
    a = Swim("a", 1, DEFAULTS, random.Random(0))
    nonce = _probe_of(a.on_heartbeat(Heartbeat("old", 1, 0), 0.0).sends, "old")
    assert a.on_heartbeat(Heartbeat("old", 1, 0, ack=nonce), 0.0).confirmed == ["old"]
    a.on_heartbeat(Heartbeat("new", 1, 0), 0.0)
    forget = DEFAULTS.forget_s(a.team())
    asked, gone, t = 0, None, 0.0
    while gone is None and t < 10:
        t = round(t + DEFAULTS.period_s, 6)
        step = a.tick(t)
        asked += sum(1 for to, m in step.sends if to == "new" and isinstance(m, Heartbeat))
        for to, m in step.sends:  # old answers every probe; new never does
            if to == "old" and isinstance(m, Heartbeat) and m.probe:
                a.on_heartbeat(Heartbeat("old", 1, 0, ack=m.probe), t + 0.001)
        if (TeamEvent.FAILED, "new") in step.events:
            gone = t
    assert gone is not None
    assert forget <= gone < forget + 2 * DEFAULTS.period_s
    assert asked >= int(forget / DEFAULTS.period_s) - 2  # asked again every period
    assert set(a.members) == {"old"}
    assert a.forgotten == 1


def test_a_flood_of_made_up_members_is_forgotten_within_the_bound_without_false_failures() -> None:
    """1,000 made-up members beat r0 every period for 5 s (each also claiming that r1
    failed), then fall silent. Bound: each is forgotten within ``forget_s(team)`` of its
    last beat plus two periods (the tick that notices; 7.4 s for this team)."""
    real = [f"r{i}" for i in range(5)]
    net = SwimNet(real, DEFAULTS, seed=3, loss=0.01)
    r0 = net.robots["r0"].swim
    r1 = net.robots["r1"].swim
    ghosts = [f"ghost-{i}" for i in range(1000)]
    told: list[str] = []  # news r0 passes on of made-up members
    net.intercept = lambda s, to, m: bool(
        s == "r0"
        and isinstance(m, Heartbeat)
        and told.extend(h.robot for h in m.heard if h.robot.startswith("ghost-"))
    )
    start, beating = 2.0, 5.0
    period = DEFAULTS.period_s
    rng = random.Random(1)
    for g in ghosts:
        phase = rng.uniform(0, period)
        liar = [Heard("r1", r1.incarnation, 0, 0, True, g)]
        for k in range(int(beating / period)):
            hb = Heartbeat(g, 1, 0, False, k, heard=liar, probe=k + 1)
            net.inject(start + phase + k * period, g, "r0", hb)
    net.run_until(start + 1.0)
    joined = sum(1 for m in r0.members if m.startswith("ghost-"))
    assert joined == len(ghosts)
    last_beat = start + beating
    bound = DEFAULTS.forget_s(len(real) + len(ghosts)) + 2 * period
    assert bound < 7.5
    net.run_until(last_beat + bound)
    assert set(r0.members) == set(real) - {"r0"}
    assert r0.forgotten == len(ghosts)
    assert told == []  # nobody was told of them
    net.run_until(60.0)
    assert [e for e in net.failures() if not e.robot.startswith("ghost-")] == []
    assert all(set(net.members_of(r)) == set(real) - {r} for r in real)
    # What asking them again cost r0: their join's probe, then a bounded share a period.
    retries = net.robots["r0"].counted["Heartbeat"]
    periods = 60.0 / period
    assert retries <= len(ghosts) * int(beating / period) + periods * (RETRIES_PER_PERIOD + 4)
