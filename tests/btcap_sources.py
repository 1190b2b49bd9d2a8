"""Where each module of the installed package ``btcap`` lives in the source tree.

pyproject.toml installs btcap/ as ``btcap`` and the design's top-level folders (actors/,
transports/, sim/, bench/) as ``btcap.actors`` and so on (setuptools ``package-dir``).
Tests that read the source walk it through that same mapping, so they see what a wheel
holds, under the names it is imported by.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SETUPTOOLS = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
#: Package -> the folder it is installed from, e.g. ``"btcap.actors": ROOT / "actors"``.
ROOTS = {package: ROOT / folder for package, folder in SETUPTOOLS["package-dir"].items()}


def package_folders() -> dict[str, Path]:
    """Every folder holding Python files under the mapped folders, by the package name it
    is installed as (a subfolder that is itself mapped belongs to its own entry)."""
    found: dict[str, Path] = {}
    for root_package, root in ROOTS.items():
        for folder, dirs, files in os.walk(root):
            dirs[:] = sorted(d for d in dirs if d != "__pycache__" and not d.startswith("."))
            rel = Path(folder).relative_to(root).parts
            package = ".".join([root_package, *rel])
            if rel and package in ROOTS:
                dirs.clear()
                continue
            if any(f.endswith(".py") for f in files):
                found[package] = Path(folder)
    return found


def modules() -> dict[str, Path]:
    """Every module of btcap (packages by their ``__init__.py``) -> its source file."""
    found: dict[str, Path] = {}
    for package, folder in package_folders().items():
        for path in sorted(folder.glob("*.py")):
            name = package if path.stem == "__init__" else f"{package}.{path.stem}"
            found[name] = path
    return dict(sorted(found.items()))


def installed_path(path: Path) -> Path:
    """Where the source file ``path`` goes in a wheel, e.g. actors/clock.py ->
    btcap/actors/clock.py (the deepest package folder holding it decides)."""
    holders = [(p, f) for p, f in package_folders().items() if path.is_relative_to(f)]
    package, folder = max(holders, key=lambda pf: len(pf[1].parts))
    return Path(*package.split("."), path.relative_to(folder))
