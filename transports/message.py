"""The one base type every protocol message derives from, and the open registry of them."""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import msgspec

__all__ = ["Address", "Message", "MessageRegistry"]


class Message(msgspec.Struct, tag=True, array_like=True):
    """Base of all typed messages.

    Tagged with the class name so a union of registered messages decodes in one pass;
    array-like so frames stay small on the wire.
    """


class Address(msgspec.Struct, frozen=True, array_like=True):
    """Where an actor lives: the id of its actor system plus its path inside it.

    Printable as ``system/path`` and parsed back by :meth:`parse`, so addresses can go
    in logs, files and CLI arguments.
    """

    system: str
    path: str

    def __str__(self) -> str:
        return f"{self.system}/{self.path}"

    @classmethod
    def parse(cls, text: str) -> Address:
        system, sep, path = text.partition("/")
        if not sep or not system or not path:
            raise ValueError(f"address {text!r}: expected 'system/path'")
        return cls(system, path)


class MessageRegistry:
    """The set of message types a codec accepts.

    Open on purpose: lower layers register their own messages and higher layers add
    theirs, without any module-level state.
    """

    __slots__ = ("_by_tag", "_types", "_version")

    def __init__(self, types: Iterable[type[Message]] = ()) -> None:
        self._by_tag: dict[str, type[Message]] = {}
        self._types: set[type[Message]] = set()
        self._version = 0
        self.register(*types)

    def register(self, *types: type[Message]) -> None:
        for t in types:
            if not (isinstance(t, type) and issubclass(t, Message)) or t is Message:
                raise TypeError(f"{t!r} is not a subclass of transports.Message")
            tag = t.__struct_config__.tag
            if not isinstance(tag, str):
                raise TypeError(f"{t.__qualname__}: message types must use string tags")
            known = self._by_tag.get(tag)
            if known is t:
                continue
            if known is not None:
                raise ValueError(
                    f"message tag {tag!r} of {t.__module__}.{t.__qualname__} is already "
                    f"taken by {known.__module__}.{known.__qualname__}"
                )
            self._by_tag[tag] = t
            self._types.add(t)
            self._version += 1

    def merge(self, other: MessageRegistry) -> None:
        self.register(*other)

    @property
    def version(self) -> int:
        """Grows on every change so codecs know when to rebuild their decoders."""
        return self._version

    def __iter__(self) -> Iterator[type[Message]]:
        return iter(self._by_tag.values())

    def __len__(self) -> int:
        return len(self._by_tag)

    def __contains__(self, item: object) -> bool:
        return item in self._types
