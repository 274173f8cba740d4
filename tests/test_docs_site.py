"""The front page stays a front page, every docs page is reachable, and no figure in the docs is copied by hand.

The site itself is built by `mkdocs build --strict` in CI (.ci/run); these checks are the cheap part of it.
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
DOCS = REPO / "docs"
README_LIMIT_BYTES = 8 * 1024
OWN_INDEX = ("examples",)  # folders of docs/ whose pages their own index lists


def nav_pages(config: str) -> set[str]:
    """The page files named in mkdocs.yml's nav (`- Title: page.md`), without parsing its YAML tags."""
    nav = config.split("\nnav:\n", 1)[1]
    nav = re.split(r"\n\S", nav, maxsplit=1)[0]  # up to the next top-level key
    return set(re.findall(r":\s*(\S+\.md)\s*$", nav, flags=re.MULTILINE))


def test_the_readme_is_a_front_page_of_at_most_8_kb():
    size = (REPO / "README.md").stat().st_size
    assert size <= README_LIMIT_BYTES, f"README.md: {size} bytes, expected at most {README_LIMIT_BYTES}"


def test_every_docs_page_is_in_the_nav_and_every_nav_page_exists():
    listed = nav_pages((REPO / "mkdocs.yml").read_text(encoding="utf-8"))
    pages = {
        str(page.relative_to(DOCS)) for page in DOCS.rglob("*.md") if page.relative_to(DOCS).parts[0] not in OWN_INDEX
    }
    assert sorted(pages - listed) == [], "docs pages missing from mkdocs.yml's nav"
    assert sorted(listed - pages) == [], "mkdocs.yml's nav names pages that do not exist"


def test_the_nav_reader_sees_a_page_listed_and_misses_one_that_is_not():
    config = "site_name: x\nnav:\n  - Home: index.md\n  - Robots: robots.md\nplugins:\n  - search\n"
    assert nav_pages(config) == {"index.md", "robots.md"}


def test_the_docs_tables_equal_what_the_benchmark_results_render_to():
    check = subprocess.run(
        [sys.executable, "benchmarks/render_docs_tables.py", "--check"], cwd=REPO, capture_output=True, text=True
    )
    assert check.returncode == 0, check.stdout + check.stderr


def test_a_page_whose_table_differs_from_its_json_is_rendered_anew():
    sys.path.insert(0, str(REPO / "benchmarks"))
    try:
        import render_docs_tables
    finally:
        sys.path.pop(0)
    stale = "before\n<!-- table:chain_fk -->\n| a hand-copied figure |\n<!-- /table:chain_fk -->\nafter\n"
    fresh = render_docs_tables.rendered_page(stale)
    assert "hand-copied" not in fresh and "pytorch_kinematics forward_kinematics" in fresh
    assert fresh.startswith("before\n") and fresh.endswith("after\n")
    assert render_docs_tables.rendered_page(fresh) == fresh
    with pytest.raises(ValueError, match="table: expected one of"):
        render_docs_tables.rendered_page("<!-- table:nope -->\n<!-- /table:nope -->\n")


HISTORY = re.compile(r"\b(issue|finding|deliverable|session|sitting)s? (#?\d+|of \d{4})|\b\d{4}-\d{2}-\d{2}\b", re.I)


@pytest.mark.parametrize("page", ["README.md", *sorted(str(p.relative_to(REPO)) for p in DOCS.rglob("*.md"))])
def test_the_docs_say_what_is_and_cite_no_issue_session_or_date(page):
    lines = (REPO / page).read_text(encoding="utf-8").splitlines()
    cited = [f"{number}: {line}" for number, line in enumerate(lines, 1) if HISTORY.search(line)]
    assert cited == []
