"""What every file loader shares: msgspec's errors as "field: problem", and no .inf/.nan."""

from __future__ import annotations

from typing import Annotated, Literal

import msgspec
import pytest

from btcap.team.filecheck import field_first, not_finite


class Leg(msgspec.Struct):
    gait: Literal["walk", "trot"] = "walk"
    length_m: float = 1.0


class Dog(msgspec.Struct):
    legs: list[Leg] = []
    spare: Leg | None = None
    tags: dict[str, float] = {}
    mood: Annotated[Literal["calm", "eager"], msgspec.Meta(description="How it feels.")] = "calm"


def _error(raw: object) -> str:
    with pytest.raises(msgspec.ValidationError) as info:
        msgspec.convert(raw, Dog)
    return str(info.value)


@pytest.mark.parametrize(
    ("raw", "expected"),
    [
        ({"legs": [{}, {"length_m": "x"}]}, "legs[1].length_m: Expected `float`, got `str`"),
        ({"mood": "sad"}, "mood: Invalid enum value 'sad'; expected one of 'calm', 'eager'"),
        ({"legs": [{"gait": "run"}]}, "legs[0].gait: Invalid enum value 'run'; expected one of"),
        ({"spare": {"gait": "run"}}, "spare.gait: Invalid enum value 'run'; expected one of"),
        ([], "Expected `object`, got `array`"),
    ],
)
def test_errors_name_the_field_first_and_list_valid_choices(raw: object, expected: str) -> None:
    assert field_first(_error(raw), Dog).startswith(expected)


def test_without_the_type_choices_are_not_listed() -> None:
    assert field_first(_error({"mood": "sad"})) == "mood: Invalid enum value 'sad'"


def test_non_finite_numbers_are_found_anywhere() -> None:
    assert not_finite(Dog(legs=[Leg(), Leg(length_m=2.5)], tags={"a": 1.0})) is None
    inf = Dog(legs=[Leg(), Leg(length_m=float("inf"))])
    assert not_finite(inf) == ("legs[1].length_m", "expected a finite number, got inf")
    nan = Dog(spare=Leg(length_m=float("nan")))
    assert not_finite(nan) == ("spare.length_m", "expected a finite number, got nan")
    assert not_finite(Dog(tags={"speed": float("-inf")})) == (
        "tags.speed",
        "expected a finite number, got -inf",
    )
    assert not_finite(float("inf")) == ("$", "expected a finite number, got inf")


@pytest.mark.parametrize(
    ("message", "said"),
    [
        (
            "Object contains unknown field `name`",
            "Object contains unknown field `name`; expected one of legs, spare, tags, mood",
        ),
        (
            "Object contains unknown field `pace` - at `$.legs[2]`",
            "legs[2]: Object contains unknown field `pace`; expected one of gait, length_m",
        ),
    ],
)
def test_an_unknown_field_is_told_the_fields_it_could_be(message: str, said: str) -> None:
    assert field_first(message, Dog) == said
