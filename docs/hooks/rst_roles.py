"""A griffe extension for the docs build: btcap's docstrings use Sphinx roles
(:class:`~btcap.bt.tree.Tree`); render each as code linked to its API entry when the
reference has one (an optional autoref: no warning when it does not)."""

from __future__ import annotations

import re
from typing import Any

import griffe

_ROLE = re.compile(r":(?:class|func|meth|attr|mod|data|obj|exc):`(~?)([\w.]+)(\(\))?`")


def _link(match: re.Match[str]) -> str:
    short, target, call = match[1] == "~", match[2], match[3] or ""
    title = (target.rsplit(".", 1)[-1] if short else target) + call
    if "." not in target or not target.startswith("btcap."):
        return f"`{title}`"
    return f'<autoref identifier="{target}" optional><code>{title}</code></autoref>'


def convert(text: str) -> str:
    """Sphinx roles to markdown the docs can render."""
    return _ROLE.sub(_link, text)


class RstRoles(griffe.Extension):
    """Rewrites the roles of every docstring griffe loads."""

    def on_object(self, *, obj: griffe.Object, **kwargs: Any) -> None:
        if obj.docstring is not None:
            obj.docstring.value = convert(obj.docstring.value)
