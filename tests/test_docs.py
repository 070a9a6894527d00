"""The README stays a front door and every link of it and of docs/ leads somewhere."""
from __future__ import annotations

import re

from conftest import REPO

LINK = re.compile(r'\[[^\]]*\]\(([^)\s]+)\)')
README_LINES_MAX = 150
# A page of what is true now is named by its topic, never by a date or a log.
LOG_NAME = re.compile(r'history|log|\d{4}-\d{2}', re.I)
TABLE_ROW = re.compile(r'^\|.*\|\s*$', re.M)


def pages():
    return [REPO / 'README.md', *sorted((REPO / 'docs').glob('*.md'))]


def test_every_link_of_the_readme_and_the_docs_resolves():
    broken = []
    for page in pages():
        for target in LINK.findall(page.read_text()):
            if target.startswith(('http://', 'https://', '#', 'mailto:')):
                continue
            path = target.split('#', 1)[0]
            if not (page.parent / path).exists():
                broken.append(f'{page.relative_to(REPO)}: {target}')
    assert not broken, broken


def test_every_docs_page_is_linked_from_the_readmes_table():
    readme = REPO / 'README.md'
    rows = '\n'.join(TABLE_ROW.findall(readme.read_text()))
    linked = {(readme.parent / target.split('#', 1)[0]).resolve() for target in LINK.findall(rows)}
    orphans = [page.name for page in pages()[1:] if page.resolve() not in linked]
    assert not orphans, orphans


def test_no_docs_page_is_a_dated_log():
    assert [page.name for page in pages()[1:] if LOG_NAME.search(page.stem)] == []


def test_the_readme_is_short():
    assert len((REPO / 'README.md').read_text().splitlines()) <= README_LINES_MAX
