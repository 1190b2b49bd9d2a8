"""The reference generator: any msgspec Struct gives a JSON Schema and a Markdown table of
every field (path, type with bounds, default, meaning); a field left undescribed fails."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import msgspec
import pytest

from btcap.reference import FileFormat, json_schema, markdown, schema_text


def _doc(text: str, **bounds: float) -> msgspec.Meta:
    return msgspec.Meta(description=text, **bounds)


class Wheel(msgspec.Struct, forbid_unknown_fields=True):
    """One wheel."""

    radius_m: Annotated[float, _doc("Its radius.", gt=0)]
    grip: Annotated[float, _doc("How much it grips.", ge=0, lt=1)] = 0.5


class Body(msgspec.Struct, forbid_unknown_fields=True):
    """The body, with ``Sphinx`` markup and :class:`~pkg.mod.Thing` in its docstring."""

    colour: Annotated[Literal["red", "blue"], _doc("Its colour.")] = "red"
    wheels: Annotated[list[Wheel], msgspec.Meta(min_length=1, description="Its wheels.")] = (
        msgspec.field(default_factory=lambda: [Wheel(0.3)])
    )
    spare: Annotated[Wheel | None, _doc("A spare wheel, or null.")] = None


class Robot(msgspec.Struct, forbid_unknown_fields=True):
    """A robot."""

    name: Annotated[str, msgspec.Meta(min_length=1, description="Its name.")]
    body: Annotated[Body, _doc("What it is made of.")] = msgspec.field(
        default_factory=lambda: Body(colour="blue")
    )
    count: Annotated[int, _doc("How many.", ge=1, le=10)] = 1
    parts: Annotated[dict[str, Wheel], _doc("Parts by name.")] = {}
    manual: Annotated[Path | None, _doc("Where its manual is.")] = None
    origin: Annotated[
        str, msgspec.Meta(description="Set by the loader.", extra={"internal": True})
    ] = ""


ROBOT = FileFormat("robot", "Robot files", "Robot", Robot, "What a robot is.", "name: r2\n")


def test_the_schema_is_msgspecs_without_internal_fields() -> None:
    schema = json_schema(ROBOT)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert schema["$ref"] == "#/$defs/Robot"
    robot = schema["$defs"]["Robot"]
    assert "origin" not in robot["properties"]
    assert robot["required"] == ["name"]
    assert robot["additionalProperties"] is False
    assert robot["properties"]["count"] | {"default": 1} == {
        "description": "How many.",
        "type": "integer",
        "minimum": 1,
        "maximum": 10,
        "default": 1,
    }
    assert {"type": "string"} in robot["properties"]["manual"]["anyOf"]  # a path
    assert schema["$defs"]["Body"]["description"] == (
        "The body, with `Sphinx` markup and `Thing` in its docstring."
    )
    assert msgspec.json.decode(schema_text(ROBOT)) == schema


def test_the_page_lists_every_field_with_path_type_default_and_meaning() -> None:
    page = markdown(ROBOT)
    rows = {line.split(" | ")[0].strip("| `"): line for line in page.splitlines() if "| `" in line}
    assert set(rows) == {
        "name",
        "body",
        "count",
        "parts",
        "manual",
        "body.colour",
        "body.wheels",
        "body.spare",
        "body.wheels[].radius_m",
        "body.wheels[].grip",
    }
    assert rows["name"] == "| `name` | non-empty string | required | Its name. |"
    assert rows["count"] == "| `count` | integer in [1, 10] | `1` | How many. |"
    assert (
        rows["body"]
        == '| `body` | [`body`](#robot-body) | `{colour: "blue"}` | What it is made of. |'
    )
    assert "| [`body.wheels[]`](#robot-bodywheels) or null |" in rows["body.spare"]
    assert "non-empty list of [`body.wheels[]`]" in rows["body.wheels"]
    assert "`[{radius_m: 0.3}]`" in rows["body.wheels"]
    assert rows["body.colour"].startswith('| `body.colour` | one of `blue`, `red` | `"red"` |')
    assert "| number > 0 | required |" in rows["body.wheels[].radius_m"]
    assert "| number in [0, 1) | `0.5` |" in rows["body.wheels[].grip"]
    assert "mapping of name to [`body.wheels[]`]" in rows["parts"]
    assert "| path or null | `null` |" in rows["manual"]
    assert "origin" not in page
    headings = [line for line in page.splitlines() if line.startswith("#")]
    assert headings == [
        "## Robot files",
        "### Robot top level",
        "### Robot `body`",
        "### Robot `body.wheels[]`",
    ]
    assert "The same fields at `body.wheels[]`, `body.spare`, `parts.NAME`." in page
    assert "```yaml\nname: r2\n```" in page


def test_a_field_without_a_description_is_an_error() -> None:
    class Loose(msgspec.Struct):
        """A file with a hole."""

        known: Annotated[int, _doc("Described.")] = 0
        unknown: int = 0

    fmt = FileFormat("loose", "Loose files", "Loose", Loose, "A file.")
    with pytest.raises(ValueError, match="loose: unknown: no description"):
        markdown(fmt)
