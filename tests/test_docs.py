"""The docs' generated parts (copies of example files, the CLI reference) are current."""

from __future__ import annotations

import re
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


def _pages() -> list[Path]:
    return [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]


def _prose(page: Path) -> str:
    """A page without its fenced code blocks (whose brackets are code, not links)."""
    return re.sub(r"^```.*?^```", "", page.read_text(encoding="utf-8"), flags=re.M | re.S)


def test_no_reference_reads_as_raw_text_on_a_code_host() -> None:
    """``[Name][btcap.x.Name]`` works only in the built site (mkdocs-autorefs); a code
    host shows it as it is. Plain links (``[Name](api/team.md#btcap.x.Name)``) work in
    both."""
    for page in _pages():
        raw = re.findall(r"\]\[[\w.]+\]", _prose(page))
        assert not raw, f"{page.relative_to(ROOT)}: {raw}: write [text](api/PAGE.md#id)"


def test_relative_links_lead_to_a_file_of_the_checkout() -> None:
    """Every relative link of a page names a file beside it (as a code host reads it);
    the anchors into the API pages are checked by ``make docs`` (strict)."""
    for page in _pages():
        for url in re.findall(r"\]\(([^)\s]+)\)", _prose(page)):
            if re.match(r"[a-z]+:", url) or url.startswith("#"):
                continue
            target = (page.parent / url.partition("#")[0]).resolve()
            assert target.exists(), f"{page.relative_to(ROOT)}: link {url}: no such file"
