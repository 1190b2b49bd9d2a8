"""The paper's mission tree: Parallel(Explore, Sequence(Identify Object, Move to
Decontamination)), each leaf a capability, looped until the cave is explored and every
contaminated object is decontaminated."""

from __future__ import annotations

from btcap import (
    Compare,
    Fallback,
    ForceSuccess,
    Node,
    Parallel,
    RepeatUntilFailure,
    Sequence,
    Tree,
)
from btcap.sim.mission.capabilities import DECONTAMINATE, EXPLORE, IDENTIFY
from btcap.sim.mission.leaves import ClaimWork

__all__ = ["mission_tree"]


def mission_tree(*, object_workers: int = 1, store: str = "sim/store") -> Tree:
    """Build the mission; ``object_workers`` identify/decontaminate loops run in parallel.

    Each loop claims work from the shared store, so a goal or object is worked on by one
    loop at a time, and work whose capability failed is claimed again later.
    """
    if object_workers < 1:
        raise ValueError("object_workers must be >= 1")
    next_goal = ClaimWork("next_goal", kind="goal", store=store)
    explore = EXPLORE.node_type()("explore")
    explore_loop = RepeatUntilFailure(
        "explore_loop",
        children=[
            Sequence(
                "explore_next",
                children=[next_goal, ForceSuccess("try_explore", children=[explore])],
            )
        ],
    )
    loops = [explore_loop]
    wires: list[tuple[Node, str, Node, str]] = [(next_goal, "at", explore, "goal")]
    for k in range(object_workers):
        claim = ClaimWork("next_object", kind="object", store=store)
        identify = IDENTIFY.node_type()("identify")
        dirty = Compare("is_contaminated", op="==", inputs={"b": True})
        # An object offered again after a failed decontamination is known to be dirty:
        # it is not identified a second time.
        known = Compare("known_contaminated", op="==", inputs={"b": True})
        decon = DECONTAMINATE.node_type()("decontaminate")
        check = Fallback(
            "known_or_identify",
            children=[known, Sequence("identify_then_check", children=[identify, dirty])],
        )
        handle = Sequence("identify_then_clean", children=[check, decon])
        loops.append(
            RepeatUntilFailure(
                f"object_loop_{k + 1}",
                children=[
                    Sequence(
                        "handle_next",
                        children=[claim, ForceSuccess("try_object", children=[handle])],
                    )
                ],
            )
        )
        wires += [
            (claim, "target", identify, "object"),
            (claim, "at", identify, "at"),
            (identify, "contaminated", dirty, "a"),
            (claim, "identified", known, "a"),
            (claim, "target", decon, "object"),
            (claim, "at", decon, "at"),
        ]
    tree = Tree(Parallel("mission", children=loops), name="find_and_decontaminate")
    for src, out, dst, inp in wires:
        tree.wire(src, out, dst, inp)
    return tree
