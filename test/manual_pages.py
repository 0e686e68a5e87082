"""Where the user's manual is: README.md, the front door, and the pages of docs/ in the order of the README's table
of contents (the order test_readme.py runs their commands in). docs/_incoming/ is a staging area, not the manual."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
DOCS = ROOT / 'docs'
STAGING = DOCS / '_incoming'
CONTENTS = '## The manual'
"""The README's table of contents: the heading above it."""
LINK = re.compile(r'!?\[(?:[^\]`]|`[^`]*`)*\]\(([^)\s]+)\)|<(?:img|a)\s[^>]*?(?:src|href)="([^"]+)"')
"""A Markdown link or image `[text](target)`, or an HTML `<img src>` / `<a href>`: group 1 or 2 is the target."""
FENCED = r'^(```|~~~).*?^\1[^\n]*$'
BLOCKS = re.compile(FENCED, flags=re.S | re.M)
"""Fenced code blocks: no heading inside one is a heading."""
CODE = re.compile(FENCED + r'|`[^`]*`', flags=re.S | re.M)
"""Fenced code blocks and inline code spans: no link inside them is a link."""


def docs_pages() -> list[Path]:
    """Every page of the manual in docs/ (the staging area left out)."""
    return sorted(path for path in DOCS.rglob('*.md') if STAGING not in path.parents)


def without_code(text: str, code: re.Pattern = CODE) -> str:
    """The text with its code blocks and code spans blanked (line breaks kept, so line numbers still hold)."""
    return code.sub(lambda match: re.sub(r'[^\n]', ' ', match.group()), text)


def links(text: str) -> list[str]:
    """The targets of the text's links and images, in order (links inside code are not links)."""
    return [match.group(1) or match.group(2) for match in LINK.finditer(without_code(text))]


def contents() -> list[Path]:
    """The docs pages the README's table of contents links to, in its order."""
    section = README.read_text().partition(f'\n{CONTENTS}\n')[2].split('\n## ')[0]
    listed: list[Path] = []
    for target in links(section):
        path = (ROOT / target.split('#')[0]).resolve()
        if path.suffix == '.md' and path not in listed:
            listed.append(path)
    return listed


def pages() -> list[Path]:
    """README.md, then each docs page in the order of the README's table of contents (any page it lacks last)."""
    listed = contents()
    return [README] + listed + [page for page in docs_pages() if page not in listed]


def manual_text() -> str:
    """README.md and every docs page, one after the other."""
    return '\n'.join(page.read_text() for page in pages())


def blocks(language: str) -> list[str]:
    """The contents of every fenced block of that language (```bash, ```python) in the manual, in reading order."""
    found = []
    for page in pages():
        found += re.findall(rf'^```{language}\n(.*?)^```', page.read_text(), flags=re.S | re.M)
    return found


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: its text lower-cased, punctuation dropped, spaces made hyphens."""
    text = re.sub(r'\[([^\]]*)\]\([^)]*\)', r'\1', heading)   # a link in a heading anchors by its text
    return re.sub(r'[^\w\- ]', '', text.strip().lower()).replace(' ', '-')


def anchors(text: str) -> set[str]:
    """The anchors of a page's headings, a repeated one numbered as GitHub numbers it (`-1`, `-2`, ...)."""
    found: set[str] = set()
    for heading in re.findall(r'^#{1,6}\s+(.+?)\s*#*\s*$', without_code(text, BLOCKS), flags=re.M):
        base = slug(heading)
        anchor, count = base, 0
        while anchor in found:
            count += 1
            anchor = f'{base}-{count}'
        found.add(anchor)
    return found
