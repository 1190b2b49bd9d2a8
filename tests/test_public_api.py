"""The public API: every exported name resolves, and the old module paths still work."""

from __future__ import annotations

import importlib
import sys

import pytest

import btcap


@pytest.mark.parametrize("name", sorted(btcap.__all__))
def test_every_exported_name_resolves(name: str) -> None:
    assert getattr(btcap, name) is not None


def test_all_is_unique() -> None:
    assert len(set(btcap.__all__)) == len(btcap.__all__)


@pytest.mark.parametrize(
    ("old", "name", "new"),
    [
        ("btcap.agent", "Agent", "btcap.team.agent"),
        ("btcap.demo", "ECHO", "btcap.team.demo"),
        ("btcap.protocol", "protocol_registry", "btcap.team.protocol"),
        ("btcap.capfiles", "load_interfaces", "btcap.team.capfiles"),
        ("btcap.launch", "spawn_agent", "btcap.team.spawn"),
    ],
)
def test_old_module_paths_re_export_with_a_deprecation_warning(
    old: str, name: str, new: str
) -> None:
    sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match=old):
        module = importlib.import_module(old)
    assert getattr(module, name) is getattr(importlib.import_module(new), name)
    for exported in module.__all__:
        assert hasattr(module, exported)
