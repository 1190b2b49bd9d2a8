"""A wheel of btcap holds every package and data file of the source tree, under btcap.

pyproject.toml installs the design's top-level folders (actors/, transports/, sim/,
bench/) as btcap.actors and so on (package-dir), which needs an explicit package list:
a subpackage left out of it would be missing from every wheel while the editable install,
and so the rest of the suite, still finds it. Same for a data file no package-data
pattern matches.
"""

from __future__ import annotations

import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from btcap_sources import ROOT, ROOTS, SETUPTOOLS, installed_path, package_folders

#: Tracked files in a package folder that are deliberately not installed.
NOT_SHIPPED = {"bench/results/.gitkeep"}


def _tracked() -> list[Path]:
    """The files git tracks under the folders pyproject.toml installs."""
    if not (ROOT / ".git").exists() or shutil.which("git") is None:
        pytest.skip("needs a git checkout")
    folders = sorted({str(folder.relative_to(ROOT)) for folder in ROOTS.values()})
    done = subprocess.run(
        ["git", "ls-files", "-z", "--", *folders],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return [ROOT / name for name in done.stdout.split("\0") if name]


def _shipped_data() -> set[Path]:
    """The files pyproject.toml's package-data patterns select, as setuptools globs them."""
    patterns = SETUPTOOLS["package-data"]
    found: set[Path] = set()
    for package, folder in package_folders().items():
        for pattern in [*patterns.get("*", []), *patterns.get(package, [])]:
            found.update(p for p in folder.glob(pattern) if p.is_file())
    return found


def test_every_package_folder_is_in_the_package_list() -> None:
    folders = package_folders()
    listed = set(SETUPTOOLS["packages"])
    missing = sorted(folders.keys() - listed)
    extra = sorted(listed - folders.keys())
    assert not missing, f"add to [tool.setuptools] packages in pyproject.toml: {missing}"
    assert not extra, f"listed in pyproject.toml, but no folder of Python files: {extra}"
    assert {"btcap.actors", "btcap.team.core", "btcap.sim"} <= listed


def test_every_package_folder_has_an_init() -> None:
    bare = [str(f.relative_to(ROOT)) for f in package_folders().values()]
    bare = [f for f in bare if not (ROOT / f / "__init__.py").is_file()]
    assert not bare, f"folders of Python files without __init__.py: {bare}"


def test_every_data_file_is_shipped_and_every_pattern_matches() -> None:
    data = {p for p in _tracked() if p.suffix != ".py"}
    shipped = _shipped_data()
    left_out = sorted(str(p.relative_to(ROOT)) for p in data - shipped)
    assert set(left_out) == NOT_SHIPPED, (
        f"no package-data pattern in pyproject.toml ships {sorted(set(left_out) - NOT_SHIPPED)}"
    )
    for package, patterns in SETUPTOOLS["package-data"].items():
        folders = package_folders().values() if package == "*" else [package_folders()[package]]
        for pattern in patterns:
            assert any(f.glob(pattern) for f in folders), f"{package}: {pattern} matches nothing"


def test_a_data_file_goes_where_the_code_looks_for_it() -> None:
    assert installed_path(ROOT / "sim" / "scenarios" / "full-team.yaml") == Path(
        "btcap/sim/scenarios/full-team.yaml"
    )
    assert installed_path(ROOT / "btcap" / "monitor" / "static" / "app.js") == Path(
        "btcap/monitor/static/app.js"
    )


@pytest.mark.slow
def test_the_wheel_holds_exactly_the_modules_and_data_files(tmp_path: Path) -> None:
    """Built from a copy of the tracked files (the checkout's build/ may hold stale ones)."""
    tracked = _tracked()
    source = tmp_path / "src"
    for path in [*tracked, ROOT / "pyproject.toml", ROOT / "README.md"]:
        (source / path.relative_to(ROOT)).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(path, source / path.relative_to(ROOT))
    pip = [sys.executable, "-m", "pip", "wheel", "-q", "--no-deps", "--no-build-isolation"]
    done = subprocess.run(
        [*pip, "--no-index", "-w", str(tmp_path / "wheel"), str(source)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    (wheel,) = (tmp_path / "wheel").glob("btcap-*.whl")
    with zipfile.ZipFile(wheel) as zf:
        held = {n for n in zf.namelist() if ".dist-info/" not in n}
    data = _shipped_data()
    expected = {installed_path(p) for p in tracked if p.suffix == ".py" or p in data}
    assert held == {str(p) for p in expected}
    assert "btcap/actors/clock.py" in held
