"""Services: what the parts of one actor system share, by typed key."""

from __future__ import annotations

import pytest

from btcap.actors import ActorSystem, Service, Services


class Greeter:
    def hello(self) -> str:
        return "hello"


GREETER: Service[Greeter] = Service("greeter")


def test_a_provided_service_is_found_by_its_key_and_only_by_it() -> None:
    services = Services()
    assert services.get(GREETER) is None
    greeter = Greeter()
    services.provide(GREETER, greeter)
    assert services.get(GREETER) is greeter
    # Keys compare by identity: a key of the same name is another service.
    assert services.get(Service[Greeter]("greeter")) is None


def test_one_system_has_one_provider_of_each_service() -> None:
    services = Services()
    greeter = Greeter()
    services.provide(GREETER, greeter)
    services.provide(GREETER, greeter)  # the same provider again is harmless
    with pytest.raises(ValueError, match=r"Service\('greeter'\) is already provided"):
        services.provide(GREETER, Greeter())
    assert services.get(GREETER) is greeter


def test_every_actor_system_has_services_of_its_own() -> None:
    a, b = ActorSystem("a"), ActorSystem("b")
    a.services.provide(GREETER, Greeter())
    assert b.services.get(GREETER) is None
