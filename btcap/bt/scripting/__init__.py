"""BehaviorTree.CPP 4.8's scripting language: parsed once at load, run as closures.

:func:`parse` reads a script (errors name the column), :func:`compile_script` binds it
to blackboard entries; the nodes that run scripts are in :mod:`btcap.bt.scripting.nodes`.
"""

from btcap.bt.scripting.compiler import Cell, Compiled, compile_script
from btcap.bt.scripting.lexer import ScriptSyntaxError
from btcap.bt.scripting.parser import Script, parse
from btcap.bt.scripting.values import ScriptError

__all__ = [
    "Cell",
    "Compiled",
    "Script",
    "ScriptError",
    "ScriptSyntaxError",
    "compile_script",
    "parse",
]
