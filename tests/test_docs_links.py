"""House rule: the docs' relative links resolve.

Every relative link and image in README.md, CHANGELOG.md, docs/**/*.md and the Markdown files
under src/ must point at a file or folder inside the repository, and a link to a heading
(`file.md#anchor` or `#anchor`) at a heading that exists there, with GitHub's anchor rule. Docs are
moved and rewritten; a figure in the README must keep leading to where it is measured.
Links inside code blocks and code spans are not links; web addresses are not checked (no network).
"""
import pathlib
import re
from urllib.parse import unquote

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
SKIPPED_DIRS = {".git", ".venv", "build", "devel", "data", "results", "node_modules"}

FENCE = re.compile(r"^\s*(```|~~~)")
CODE_SPAN = re.compile(r"(`+)(?:.+?)\1")
INLINE_LINK = re.compile(r"!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
REFERENCE_LINK = re.compile(r"^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$")
HEADING = re.compile(r"^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
HTML_ANCHOR = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"", re.IGNORECASE)
SCHEME = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]*:")


def doc_files(root=ROOT):
    """The Markdown files the rule covers, sorted."""
    found = [root / "README.md", root / "CHANGELOG.md"]
    for top in ("docs", "src"):
        for path in (root / top).rglob("*.md"):
            if not SKIPPED_DIRS.intersection(path.relative_to(root).parts):
                found.append(path)
    return sorted(p for p in found if p.is_file())


def prose_lines(text):
    """(line number, line) outside fenced and indented code blocks, code spans blanked."""
    in_fence = False
    previous_blank = True
    for number, line in enumerate(text.splitlines(), start=1):
        if FENCE.match(line):
            in_fence = not in_fence
            continue
        indented_code = previous_blank and (line.startswith("    ") or line.startswith("\t"))
        previous_blank = not line.strip() or (indented_code and previous_blank)
        if in_fence or indented_code:
            continue
        yield number, CODE_SPAN.sub("", line)


def slug(heading):
    """GitHub's anchor of a heading's text: inline markup dropped, lower case, punctuation out, spaces to '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    text = text.replace("`", "").replace("*", "")
    text = re.sub(r"<[^>]+>", "", text).strip().lower()
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    """Every anchor a Markdown file defines (duplicate headings get -1, -2, ... as on GitHub)."""
    seen = {}
    found = set()
    text = path.read_text(encoding="utf-8")
    for _, line in prose_lines(text):
        match = HEADING.match(line)
        if match:
            base = slug(match.group(2))
            count = seen.get(base, 0)
            seen[base] = count + 1
            found.add(base if count == 0 else f"{base}-{count}")
    found.update(HTML_ANCHOR.findall(text))
    return found


def link_targets(text):
    """(line number, target) of every inline, image and reference link in the prose."""
    for number, line in prose_lines(text):
        for match in INLINE_LINK.finditer(line):
            yield number, match.group(1)
        match = REFERENCE_LINK.match(line)
        if match:
            yield number, match.group(1)


def broken_links(path, root=ROOT):
    """One message per relative link of `path` that does not resolve inside `root`."""
    problems = []
    root = root.resolve()
    for number, target in link_targets(path.read_text(encoding="utf-8")):
        if SCHEME.match(target) or target.startswith("//"):
            continue
        file_part, _, fragment = target.partition("#")
        where = f"{path.relative_to(root)}:{number}: '{target}'"
        if file_part:
            resolved = (path.parent / unquote(file_part)).resolve()
            if root != resolved and root not in resolved.parents:
                problems.append(f"{where} points outside the repository")
                continue
            if not resolved.exists():
                problems.append(f"{where}: no such file or folder")
                continue
        else:
            resolved = path.resolve()
        if fragment and resolved.suffix == ".md" and unquote(fragment) not in anchors(resolved):
            problems.append(f"{where}: no heading with anchor '#{fragment}' in {resolved.relative_to(root)}")
    return problems


@pytest.mark.parametrize("path", doc_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(path):
    problems = broken_links(path)
    assert not problems, "broken links:\n" + "\n".join(problems)


def test_the_rule_covers_the_readme_and_the_docs():
    names = {str(p.relative_to(ROOT)) for p in doc_files()}
    assert {"README.md", "docs/benchmarks.md", "docs/perception.md"} <= names


def test_slug_follows_githubs_anchor_rule():
    assert slug("LiDAR (VLP-16)") == "lidar-vlp-16"
    assert slug("Navigation (move_base, navfn, DWA, costmaps)") == "navigation-move_base-navfn-dwa-costmaps"
    assert slug("Perception (the paper's Tables 2 and 3)") == "perception-the-papers-tables-2-and-3"
    assert slug("`scene_segmenter.pt`: the default") == "scene_segmenterpt-the-default"


def test_the_rule_catches_a_missing_file_a_missing_anchor_and_an_escape(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "b.md").write_text("# Title\n\n## Speed (2 cores)\n\n## Speed (2 cores)\n")
    (tmp_path / "img.png").write_bytes(b"")
    doc = tmp_path / "README.md"
    doc.write_text(
        "# Top\n\n"
        "[ok](docs/b.md) [ok](docs/b.md#speed-2-cores) [ok](docs/b.md#speed-2-cores-1) ![ok](img.png)\n"
        "[ok](#top) [web](https://example.org/x.md) `[code](nowhere.md)`\n\n"
        "    [indented code](nowhere.md)\n\n"
        "```\n[fenced](nowhere.md)\n```\n"
        "[gone](docs/missing.md)\n"
        "[no anchor](docs/b.md#speed)\n"
        "[own anchor](#bottom)\n"
        "![gone](pics/missing.png)\n"
        "[outside](../elsewhere.md)\n"
        "[ref]: docs/also_missing.md\n")
    problems = broken_links(doc, root=tmp_path)
    assert len(problems) == 6, problems
    for expected in ("docs/missing.md", "#speed'", "#bottom", "pics/missing.png", "outside the repository",
                     "docs/also_missing.md"):
        assert any(expected in p for p in problems), (expected, problems)
