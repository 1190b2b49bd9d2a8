"""The auction bench's floor: a hand-written round with bidders in other processes runs
message for message what btcap's does, with messages of btcap's sizes."""

from __future__ import annotations

import anyio
import pytest

from btcap.bench.speed.auction_floor import SIZES, VARIANTS, floor_round
from btcap.bench.speed.auction_floor_peers import message
from btcap.team.demo import ECHO
from btcap.team.ids import AuctionId, ExecutionId
from btcap.team.messages import Award, AwardReply, Bid, CallForBids, CancelExecution
from btcap.team.runtime.mission import MissionControl
from btcap.team.runtime.protocol import protocol_registry
from btcap.transports import Address
from btcap.transports.codec import Codec, Envelope, Kind


@pytest.mark.parametrize("curve", [False, True], ids=["plain", "curve"])
@pytest.mark.parametrize("variant", VARIANTS)
async def test_every_round_awards_the_cheapest_of_the_invited(variant: str, curve: bool) -> None:
    with anyio.fail_after(30):
        async with floor_round(variant, bidders=5, processes=2, curve=curve) as floor:
            assert len(floor.pids) == 2
            for n in (1, 3, 5, 5, 2):
                # bidder i bids 1 + i: the cheapest invited is always bidder 0
                assert await floor.round(n) == 0


def test_the_floors_messages_are_as_big_as_btcaps_frames() -> None:
    codec = Codec(protocol_registry())
    auction, execution = AuctionId("origin", 17, 1), ExecutionId("origin", "bench/10", 17)
    inputs = {"value": 1, "stop": False}
    auctioneer, system = Address("origin", "auctioneer"), Address("origin", "$system")
    mission = Address("b03", MissionControl.PATH)
    ask, reply, tell = Kind.ASK, Kind.REPLY, Kind.TELL
    sent = {
        "call": (tell, auctioneer, mission, CallForBids(auction, ECHO.name, ECHO.identity, inputs)),
        "bid": (tell, mission, auctioneer, Bid(auction, "b03", 4.0, "echo")),
        "award": (ask, system, mission, Award(auction, execution, ECHO.name, "echo", inputs, 3.0)),
        "accept": (reply, mission, system, AwardReply(execution, "b03", True, stamp=12.5)),
        "cancel": (tell, system, mission, CancelExecution(execution, "bench")),
    }
    for (name, size), kind in zip(SIZES.items(), range(5), strict=True):
        how, sender, recipient, msg = sent[name]
        frame = 1 + len(codec.encode(Envelope(how, sender, recipient, msg, 1000)))
        assert abs(size - frame) <= 2, (name, frame)  # a kind byte, then the envelope
        assert len(message(kind, 17, 3, 4.0)) == size, name
