"""The docs' generated parts (copies of example files, the CLI reference) are current."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_generated_parts_of_the_docs_are_current() -> None:
    done = subprocess.run(
        [sys.executable, "docs/hooks/generate.py", "--check"],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert done.returncode == 0, f"run `python docs/hooks/generate.py`:\n{done.stdout}{done.stderr}"


def test_pages_read_as_plain_markdown() -> None:
    """Nothing is included at build time: a code host shows every page as it is."""
    for page in [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]:
        text = page.read_text(encoding="utf-8")
        assert "--8<--" not in text, f"{page.relative_to(ROOT)}: a build-time include"
