"""The lock files (requirements.txt, requirements-dev.txt) cover what pyproject.toml asks for.

`make run` and `make test` install from the lock files alone (exact versions with hashes,
no dependency resolution of their own), so a requirement added to pyproject.toml without
`make lock` would be missing on a fresh machine; this says so before CI does.
"""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

import pytest
from packaging.markers import Marker
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name

ROOT = Path(__file__).resolve().parent.parent
PIN = re.compile(r"^([A-Za-z0-9][A-Za-z0-9._-]*)==([^\s;\\]+)\s*(?:;\s*([^\\]+?))?\s*\\?$")


def _pins(lock: Path) -> dict[str, list[tuple[str, str | None]]]:
    """Name -> [(version, marker)] of every pinned line (universal locks repeat names)."""
    pins: dict[str, list[tuple[str, str | None]]] = {}
    for line in lock.read_text().splitlines():
        m = PIN.match(line)
        if m:
            pins.setdefault(canonicalize_name(m[1]), []).append((m[2], m[3]))
    return pins


def _wanted(extras: list[str]) -> list[Requirement]:
    """The requirements of btcap with ``extras``, self-references (btcap[...]) expanded."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    reqs = [Requirement(r) for r in project["dependencies"]]
    todo, seen = list(extras), set()
    while todo:
        extra = todo.pop()
        if extra in seen:
            continue
        seen.add(extra)
        for text in project["optional-dependencies"][extra]:
            r = Requirement(text)
            if canonicalize_name(r.name) == "btcap":
                todo.extend(r.extras)
            else:
                reqs.append(r)
    return reqs


@pytest.mark.parametrize(
    ("lock", "extras"), [("requirements.txt", []), ("requirements-dev.txt", ["dev"])]
)
def test_every_requirement_is_pinned_in_the_lock(lock: str, extras: list[str]) -> None:
    pins = _pins(ROOT / lock)
    assert pins, f"{lock} pins nothing"
    problems = []
    for req in _wanted(extras):
        if req.marker is not None and not req.marker.evaluate():
            continue
        found = pins.get(canonicalize_name(req.name))
        if not found:
            problems.append(f"{req} is not in {lock}")
            continue
        here = [v for v, marker in found if marker is None or Marker(marker).evaluate()]
        if not any(req.specifier.contains(v, prereleases=True) for v in here):
            problems.append(f"{req}: {lock} pins {here}")
    assert not problems, "run `make lock`: " + "; ".join(problems)


def test_the_dev_lock_agrees_with_the_run_lock() -> None:
    """`make run` then `make test` share a venv: one version of each package in both."""
    run, dev = (_pins(ROOT / f) for f in ("requirements.txt", "requirements-dev.txt"))
    versions = {
        name: ({v for v, _ in run[name]}, {v for v, _ in dev.get(name, [])}) for name in run
    }
    differ = {name: pair for name, pair in versions.items() if pair[0] != pair[1]}
    assert not differ, f"run `make lock`: the locks differ on {differ}"


def test_the_ros_lock_pins_the_ros2_extra_and_agrees_with_the_run_lock() -> None:
    """.venv-ros (`make ros`) installs requirements-ros.txt alone and sees .venv's
    packages: every ``ros2`` requirement pinned there, and what both venvs hold (numpy,
    PyYAML) at the version .venv has, so neither shadows the other with another one."""
    ros = _pins(ROOT / "requirements-ros.txt")
    extra = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    missing = [
        text
        for text in extra["optional-dependencies"]["ros2"]
        if canonicalize_name(Requirement(text).name) not in ros
    ]
    assert not missing, f"run `make lock-ros`: requirements-ros.txt lacks {missing}"
    run = _pins(ROOT / "requirements.txt")
    here = {
        name: {v for v, m in pins if m is None or Marker(m).evaluate()}
        for name, pins in run.items()
    }
    differ = {
        name: (versions, here[name])
        for name, pins in ros.items()
        if name in here and (versions := {v for v, _ in pins}) != here[name]
    }
    assert not differ, f"run `make lock-ros`: requirements-ros.txt differs on {differ}"
