"""btcap: behavior trees whose capability nodes are auctioned to the best robot at run time."""

from btcap.composites import (
    Fallback,
    FallbackWithMemory,
    IfThenElse,
    Parallel,
    Sequence,
    SequenceWithMemory,
    Switch,
)
from btcap.decorators import (
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
from btcap.leaves import (
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
from btcap.node import Leaf, Node, Observer
from btcap.ports import Port
from btcap.protocol import protocol_registry
from btcap.state import IllegalTransition, State, TreeError
from btcap.tree import Subtree, Tree, Wire
from btcap.utility import Utility

__version__ = "0.1.0"

__all__ = [
    "Action",
    "AlwaysFailure",
    "AlwaysRunning",
    "AlwaysSuccess",
    "Compare",
    "Condition",
    "Constant",
    "Decorator",
    "Delay",
    "Fallback",
    "FallbackWithMemory",
    "FailureIsRunning",
    "ForceFailure",
    "ForceSuccess",
    "IfThenElse",
    "IllegalTransition",
    "Inverter",
    "Leaf",
    "Log",
    "Node",
    "Observer",
    "Parallel",
    "Port",
    "Repeat",
    "RepeatUntilFailure",
    "RepeatUntilSuccess",
    "Retry",
    "RunOnce",
    "RunningIsFailure",
    "RunningIsSuccess",
    "Sequence",
    "SequenceWithMemory",
    "State",
    "Subtree",
    "SuccessIsRunning",
    "Switch",
    "Throttle",
    "Timeout",
    "Tree",
    "TreeError",
    "Utility",
    "Wait",
    "Wire",
    "protocol_registry",
]
