"""The documentation speaks to users: every relative link resolves, and no team-internal
words (people's roles, issue numbers) appear."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DOCS = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def test_relative_links_resolve():
    bad = []
    for doc in DOCS:
        for target in re.findall(r"\]\(([^)\s]+)\)", doc.read_text()):
            if re.match(r"[a-z]+://|mailto:|#", target):
                continue
            path = (doc.parent / target.split("#")[0]).resolve()
            if not path.exists():
                bad.append(f"{doc.relative_to(REPO)} -> {target}")
    assert not bad, bad


def test_no_team_internal_words():
    pattern = re.compile(r"engineer [A-Z][0-9]|\bthe lead\b|\blead's\b|\bthe issue's\b|"
                         r"\bissue[- ]?[0-9]+\b|\bthis session\b|PHYSICS\.md|"
                         r"ARCHITECTURE\.md|STYLE\.md")
    hits = []
    for doc in DOCS + sorted((REPO / "render_inspect").rglob("*.py")):
        for i, line in enumerate(doc.read_text().splitlines(), 1):
            if pattern.search(line):
                hits.append(f"{doc.relative_to(REPO)}:{i}: {line.strip()}")
    assert not hits, hits
