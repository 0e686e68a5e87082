"""Every relative link and image of README.md and docs/*.md resolves: the file is there and an `#anchor` is one of
its headings' (as GitHub makes them); and every page of docs/ is in the README's table of contents, so a reader finds
it and its commands run in that order (test_readme.py). docs/_incoming/ is a staging area and left out."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from manual_pages import ROOT, STAGING, anchors, contents, docs_pages, links, pages, slug

EXTERNAL = re.compile(r'^[a-z][a-z0-9+.-]*:', flags=re.I)
"""https:, mailto: and the like: not checked here (no network in the suite)."""


def broken_links(page: Path, root: Path = ROOT) -> list[str]:
    """The page's relative links that lead nowhere (or out of `root`, the repository), each with why."""
    broken = []
    for target in links(page.read_text()):
        if EXTERNAL.match(target):
            continue
        path_part, _, anchor = target.partition('#')
        path = (page.parent / path_part).resolve() if path_part else page
        if not path.exists():
            broken.append(f'{target}: no file {path}')
        elif root not in path.parents:
            broken.append(f'{target}: outside the repository')
        elif anchor and path.suffix == '.md' and anchor not in anchors(path.read_text()):
            broken.append(f'{target}: no heading of {path.name} has the anchor #{anchor}')
    return broken


@pytest.mark.parametrize('page', pages(), ids=lambda page: str(page.relative_to(ROOT)))
def test_every_link_resolves(page: Path) -> None:
    assert broken_links(page) == []


def test_every_page_is_in_the_readmes_contents_and_starts_with_what_it_is_for() -> None:
    assert [page.name for page in docs_pages() if page not in contents()] == []
    for page in docs_pages():
        lines = page.read_text().splitlines()
        purpose = lines[2] if len(lines) > 2 and lines[1] == '' else ''
        assert lines[0].startswith('# ') and purpose.strip() and not purpose.startswith(('#', '|', '!', '`', '<')), \
            f'{page.name} does not start with its title and a line saying what it is for'


def test_the_staging_area_is_not_the_manual() -> None:
    assert (STAGING / 'README.md').is_file()
    assert not any(STAGING in page.parents for page in pages())


def test_the_checker_finds_what_is_broken(tmp_path: Path) -> None:
    """The check can fail: a missing file, a missing anchor, a link inside code that is no link, GitHub's slugs."""
    (tmp_path / 'other.md').write_text('# The simulator (`sim`)\n\n## Bags\n\n## Bags\n')
    page = tmp_path / 'page.md'
    page.write_text('[a](other.md#the-simulator-sim) [b](other.md#bags-1) [c](missing.md) [d](other.md#nowhere)\n'
                    '![e](img.png) <img src="other.md"> `[f](inside-code.md)`\n```bash\n[g](in-block.md)\n```\n'
                    '[h](#here)\n\n## Here\n')
    broken = [line.split(':')[0] for line in broken_links(page, tmp_path)]
    assert broken == ['missing.md', 'other.md#nowhere', 'img.png']
    assert broken_links(page, tmp_path / 'elsewhere')[0].endswith('outside the repository')
    assert slug('Quick start (a fresh machine with Python 3.10–3.13, no ROS)') == \
        'quick-start-a-fresh-machine-with-python-310313-no-ros'
