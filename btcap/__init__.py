"""btcap: behavior trees whose capability nodes are auctioned to the best robot at run time.

The behavior-tree core lives in :mod:`btcap.bt`, capabilities and the team in
:mod:`btcap.team`; what most programs need is re-exported here.
"""

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from btcap.bt.async_nodes import (
        AsyncFallback,
        AsyncSequence,
        AsyncSequenceWithMemory,
        LatchedIfThenElse,
        ParallelAll,
        WhileDoElse,
    )
    from btcap.bt.blackboard import Blackboard
    from btcap.bt.composites import (
        Fallback,
        IfThenElse,
        Parallel,
        ReactiveFallback,
        ReactiveSequence,
        Sequence,
        SequenceWithMemory,
    )
    from btcap.bt.decorators import (
        Decorator,
        Delay,
        FailureIsRunning,
        ForceFailure,
        ForceSuccess,
        Inverter,
        Repeat,
        RepeatUntilFailure,
        RepeatUntilSuccess,
        Retry,
        RunningIsFailure,
        RunningIsSuccess,
        RunOnce,
        SuccessIsRunning,
        Throttle,
        Timeout,
    )
    from btcap.bt.files import (
        TreeFile,
        TreeFileError,
        TreeFileWarning,
        dump_tree,
        dumps_tree,
        load_tree,
        loads_tree,
        save_tree,
        validate_file,
    )
    from btcap.bt.foreach import ParallelForEach
    from btcap.bt.leaves import (
        Action,
        AlwaysFailure,
        AlwaysRunning,
        AlwaysSuccess,
        Compare,
        Condition,
        Constant,
        Log,
        Wait,
    )
    from btcap.bt.node import Leaf, Node, Observer
    from btcap.bt.ports import Port
    from btcap.bt.registry import NodeRegistry, RegistryError, default_registry
    from btcap.bt.render import render_dot, render_text
    from btcap.bt.state import (
        FAILED,
        RUNNING,
        SUCCEEDED,
        BtcapWarning,
        IllegalTransition,
        NodeErrorWarning,
        RestartLoopWarning,
        State,
        TreeError,
        TreeTimeout,
        UnassignableWarning,
    )
    from btcap.bt.switch import Switch
    from btcap.bt.tree import Subtree, Tree, Wire
    from btcap.bt.utility import Utility
    from btcap.errors import BtcapError, HandshakeWarning
    from btcap.monitor import Monitor, Replay
    from btcap.team.allocation.strategies import BatchStrategy
    from btcap.team.allocation.strategy import Allocator, RobotContext, Strategy
    from btcap.team.capabilities.capability import (
        Capability,
        CapabilityInterface,
        InputBridge,
        OutputBridge,
    )
    from btcap.team.capabilities.capfiles import load_implementation, load_interfaces
    from btcap.team.capabilities.implementation import Implementation, Precondition, Scope
    from btcap.team.capabilities.slot import RemoteCapabilitySlot
    from btcap.team.core.task import Assigned, AssignmentTask, Unassigned
    from btcap.team.core.turns import BatchPolicy
    from btcap.team.ids import AuctionId, ExecutionId
    from btcap.team.runtime.agent import Agent, AgentConfig
    from btcap.team.runtime.protocol import protocol_registry
    from btcap.team.settings import MissionConfig

__version__ = "0.1.0"

#: What each module gives the public API; imported on first use (see btcap._lazy).
_EXPORTS = {
    "btcap.bt.async_nodes": (
        "AsyncFallback",
        "AsyncSequence",
        "AsyncSequenceWithMemory",
        "LatchedIfThenElse",
        "ParallelAll",
        "WhileDoElse",
    ),
    "btcap.bt.composites": (
        "Fallback",
        "IfThenElse",
        "Parallel",
        "ReactiveFallback",
        "ReactiveSequence",
        "Sequence",
        "SequenceWithMemory",
    ),
    "btcap.bt.switch": ("Switch",),
    "btcap.bt.foreach": ("ParallelForEach",),
    "btcap.bt.decorators": (
        "Decorator",
        "Delay",
        "FailureIsRunning",
        "ForceFailure",
        "ForceSuccess",
        "Inverter",
        "Repeat",
        "RepeatUntilFailure",
        "RepeatUntilSuccess",
        "Retry",
        "RunningIsFailure",
        "RunningIsSuccess",
        "RunOnce",
        "SuccessIsRunning",
        "Throttle",
        "Timeout",
    ),
    "btcap.bt.files": (
        "TreeFile",
        "TreeFileError",
        "TreeFileWarning",
        "dump_tree",
        "dumps_tree",
        "load_tree",
        "loads_tree",
        "save_tree",
        "validate_file",
    ),
    "btcap.bt.leaves": (
        "Action",
        "AlwaysFailure",
        "AlwaysRunning",
        "AlwaysSuccess",
        "Compare",
        "Condition",
        "Constant",
        "Log",
        "Wait",
    ),
    "btcap.bt.node": ("Leaf", "Node", "Observer"),
    "btcap.bt.ports": ("Port",),
    "btcap.bt.registry": ("NodeRegistry", "RegistryError", "default_registry"),
    "btcap.bt.render": ("render_dot", "render_text"),
    "btcap.bt.state": (
        "FAILED",
        "RUNNING",
        "SUCCEEDED",
        "BtcapWarning",
        "IllegalTransition",
        "NodeErrorWarning",
        "RestartLoopWarning",
        "State",
        "TreeError",
        "TreeTimeout",
        "UnassignableWarning",
    ),
    "btcap.bt.blackboard": ("Blackboard",),
    "btcap.bt.tree": ("Subtree", "Tree", "Wire"),
    "btcap.bt.utility": ("Utility",),
    "btcap.errors": ("BtcapError", "HandshakeWarning"),
    "btcap.monitor": ("Monitor", "Replay"),
    "btcap.team.runtime.agent": ("Agent", "AgentConfig"),
    "btcap.team.capabilities.capability": (
        "Capability",
        "CapabilityInterface",
        "InputBridge",
        "OutputBridge",
    ),
    "btcap.team.capabilities.capfiles": ("load_implementation", "load_interfaces"),
    "btcap.team.settings": ("MissionConfig",),
    "btcap.team.ids": ("AuctionId", "ExecutionId"),
    "btcap.team.core.task": ("Assigned", "AssignmentTask", "Unassigned"),
    "btcap.team.core.turns": ("BatchPolicy",),
    "btcap.team.capabilities.implementation": ("Implementation", "Precondition", "Scope"),
    "btcap.team.runtime.protocol": ("protocol_registry",),
    "btcap.team.capabilities.slot": ("RemoteCapabilitySlot",),
    "btcap.team.allocation.strategies": ("BatchStrategy",),
    "btcap.team.allocation.strategy": ("Allocator", "RobotContext", "Strategy"),
}

if not TYPE_CHECKING:
    from btcap._lazy import lazy_exports

    __getattr__, __dir__ = lazy_exports(__name__, _EXPORTS)

__all__ = [
    "FAILED",
    "RUNNING",
    "SUCCEEDED",
    "Action",
    "Agent",
    "AgentConfig",
    "Allocator",
    "AlwaysFailure",
    "AlwaysRunning",
    "AlwaysSuccess",
    "Assigned",
    "AssignmentTask",
    "AsyncFallback",
    "AsyncSequence",
    "AsyncSequenceWithMemory",
    "AuctionId",
    "BatchPolicy",
    "BatchStrategy",
    "Blackboard",
    "BtcapError",
    "BtcapWarning",
    "Capability",
    "CapabilityInterface",
    "Compare",
    "Condition",
    "Constant",
    "Decorator",
    "Delay",
    "ExecutionId",
    "FailureIsRunning",
    "Fallback",
    "ForceFailure",
    "ForceSuccess",
    "HandshakeWarning",
    "IfThenElse",
    "IllegalTransition",
    "Implementation",
    "InputBridge",
    "Inverter",
    "LatchedIfThenElse",
    "Leaf",
    "Log",
    "MissionConfig",
    "Monitor",
    "Node",
    "NodeErrorWarning",
    "NodeRegistry",
    "Observer",
    "OutputBridge",
    "Parallel",
    "ParallelAll",
    "ParallelForEach",
    "Port",
    "Precondition",
    "ReactiveFallback",
    "ReactiveSequence",
    "RegistryError",
    "RemoteCapabilitySlot",
    "Repeat",
    "RepeatUntilFailure",
    "RepeatUntilSuccess",
    "Replay",
    "RestartLoopWarning",
    "Retry",
    "RobotContext",
    "RunOnce",
    "RunningIsFailure",
    "RunningIsSuccess",
    "Scope",
    "Sequence",
    "SequenceWithMemory",
    "State",
    "Strategy",
    "Subtree",
    "SuccessIsRunning",
    "Switch",
    "Throttle",
    "Timeout",
    "Tree",
    "TreeError",
    "TreeFile",
    "TreeFileError",
    "TreeFileWarning",
    "TreeTimeout",
    "UnassignableWarning",
    "Unassigned",
    "Utility",
    "Wait",
    "WhileDoElse",
    "Wire",
    "default_registry",
    "dump_tree",
    "dumps_tree",
    "load_implementation",
    "load_interfaces",
    "load_tree",
    "loads_tree",
    "protocol_registry",
    "render_dot",
    "render_text",
    "save_tree",
    "validate_file",
]
