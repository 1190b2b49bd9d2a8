"""What one BehaviorTree of a BehaviorTree.CPP XML file does with blackboard entries:
the ports (and scripts) that write and read each one, as the element reader finds them."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

from btcap.bt.files.schema import NodeSpec
from btcap.bt.scripting import Script

__all__ = ["Ref", "Scope"]


@dataclasses.dataclass(frozen=True)
class Ref:
    """One node port using a blackboard entry."""

    path: str
    port: str
    line: int
    type: Any


@dataclasses.dataclass
class Scope:
    """The blackboard of one BehaviorTree, as the ports that write and read each entry."""

    tree: str
    writers: dict[str, list[Ref]] = dataclasses.field(default_factory=dict)
    readers: dict[str, list[Ref]] = dataclasses.field(default_factory=dict)
    constants: dict[str, tuple[NodeSpec, str]] = dataclasses.field(default_factory=dict)
    #: Entries a node of unknown type uses: whether it writes them is unknown, so no
    #: follow-up error is reported for them.
    unsure: set[str] = dataclasses.field(default_factory=set)
    #: Entries scripts use: (the node running the script, whether it assigns the entry).
    scripted: dict[str, list[tuple[Ref, bool]]] = dataclasses.field(default_factory=dict)
    #: Paths of the nodes running scripts, in document order.
    script_nodes: list[str] = dataclasses.field(default_factory=list)

    def add_script(self, script: Script, path: str, line: int, enums: Mapping[str, int]) -> None:
        """The entries a script of the node at ``path`` uses are blackboard entries."""
        if path not in self.script_nodes[-1:]:
            self.script_nodes.append(path)
        for key in dict.fromkeys((*script.reads, *script.writes)):
            if key not in enums:
                ref = Ref(path, "", line, Any)
                self.scripted.setdefault(key, []).append((ref, key in script.writes))
