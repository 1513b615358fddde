"""The documentation's links: every relative link and picture in README.md and docs/ points to a file
that exists (and, with an #anchor, to a heading of that file); the README stays a front door."""
import re
from pathlib import Path
from urllib.parse import unquote

import pytest

ROOT = Path(__file__).resolve().parents[2]
README_MAX_LINES = 200

PAGES = [ROOT / "README.md"] + sorted((ROOT / "docs").rglob("*.md"))

LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
FENCE = re.compile(r"^\s*(```|~~~)")
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")


def _prose(text, code_spans=False):
    """The page's lines outside fenced code blocks, with inline code spans removed unless asked."""
    inside = False
    for n, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line):
            inside = not inside
            continue
        if not inside:
            yield n, line if code_spans else re.sub(r"`[^`]*`", "", line)


def slug(heading):
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = text.replace("`", "").strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    seen, out = {}, set()
    for _, line in _prose(path.read_text(encoding="utf-8"), code_spans=True):
        m = HEADING.match(line)
        if m:
            base = slug(m.group(2))
            k = seen.get(base, 0)
            seen[base] = k + 1
            out.add(base if k == 0 else f"{base}-{k}")
    return out


def links(path):
    # a link inside `code` is no link
    for n, line in _prose(path.read_text(encoding="utf-8")):
        for m in LINK.finditer(line):
            yield n, m.group(1)


def test_pages_found():
    assert (ROOT / "README.md").exists()
    assert len(PAGES) > 10


def test_readme_is_short():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines (at most {README_MAX_LINES})"


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(page):
    broken = []
    for n, target in links(page):
        if re.match(r"^[a-z][a-z0-9+.-]*:", target, re.I):     # http:, https:, mailto:
            continue
        path_part, _, anchor = target.partition("#")
        dest = page if not path_part else (page.parent / unquote(path_part)).resolve()
        where = f"{page.relative_to(ROOT)}:{n}: {target}"
        if not dest.exists():
            broken.append(f"{where} (no such file)")
        elif anchor and dest.suffix == ".md" and anchor not in anchors(dest):
            broken.append(f"{where} (no heading #{anchor})")
        elif path_part and ROOT not in dest.parents and dest != ROOT:
            broken.append(f"{where} (outside the repository)")
    assert not broken, "broken links:\n" + "\n".join(broken)


def test_slug_is_githubs():
    assert slug("What `pdeface demo` writes") == "what-pdeface-demo-writes"
    assert slug("The eyes' rims 0.6 mm apart") == "the-eyes-rims-06-mm-apart"
    assert slug("1. A face") == "1-a-face"
    assert slug("Face model (.npz)") == "face-model-npz"
