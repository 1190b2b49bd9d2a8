"""Tree files: one versioned schema, in YAML or JSON, loaded into Trees and written back.

A file holds a root node (type, name, options, constant inputs, children), the data
wires between node ports, named subtrees (inline or in other files) usable as
``{type: Subtree, options: {tree: NAME}}`` nodes, and the ports it makes public when
it is itself used as a subtree::

    btcap: 1
    name: patrol
    root:
      type: Sequence
      name: root
      children:
        - {type: Constant, name: goal, options: {value: [1.0, 2.0], type: "list[float]"}}
        - {type: Subtree, name: go, options: {tree: goto}}
    wires:
      - {from: root/goal.value, to: root/go.goal}
    subtrees:
      goto:
        root: {type: Log, name: say, options: {message: moving}}
        public: {inputs: {goal: say.value}}

Every problem is reported with the file, the node path and the field; loading checks
everything it can before giving up, so one run shows all the mistakes in a file.

The package holds the :mod:`~btcap.bt.files.schema`, :mod:`~btcap.bt.files.parse`
(text to a checked document), :mod:`~btcap.bt.files.build` (document to Tree),
:mod:`~btcap.bt.files.load` and :mod:`~btcap.bt.files.dump` (Tree to document, text, file).
BehaviorTree.CPP v4 XML (``.xml``) is read too: :mod:`~btcap.bt.files.btcpp` translates
it into the same schema, so it is built and checked like any other file.
"""

from btcap.bt.files.dump import dump_tree, dumps_tree, save_tree
from btcap.bt.files.load import TreeFileWarning, load_tree, loads_tree, validate_file
from btcap.bt.files.parse import read_tree_file
from btcap.bt.files.schema import (
    SCHEMA_VERSION,
    FileInfo,
    NodeSpec,
    PublicSpec,
    SubtreeSpec,
    TreeFile,
    TreeFileError,
    WireSpec,
    file_info,
)

__all__ = [
    "SCHEMA_VERSION",
    "FileInfo",
    "NodeSpec",
    "PublicSpec",
    "SubtreeSpec",
    "TreeFile",
    "TreeFileError",
    "TreeFileWarning",
    "WireSpec",
    "dump_tree",
    "dumps_tree",
    "file_info",
    "load_tree",
    "loads_tree",
    "read_tree_file",
    "save_tree",
    "validate_file",
]
