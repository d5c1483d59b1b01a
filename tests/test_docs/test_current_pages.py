"""User pages hold current answers; the lab journal holds the story.

For the pages that state results (:data:`CURRENT_PAGES`):

* no dated narrative: no clock times (``06:23 UTC``), no load averages, no
  "History", "Status" or "superseded" section (docs/journal/ has them);
  what a generated table prints about its own record (a ceiling's date)
  is the record's, not the page's story;
* every table of figures is a generated region (``<!-- table: ... -->``,
  cbnet_lab/doc_tables.py, checked against its record by
  test_docs.py): no hand-typed results table;
* every ``mean +- std`` the prose quotes is in one of the page's generated
  tables, so a record that changes fails the prose that still quotes the
  old figure;
* the journal is linked, but it is never the first link a page leads to.

The journal's own links (files and anchors) resolve as the user pages' do.
"""
import glob
import os.path as osp
import re

import pytest
from doc_helpers import FENCE, ROOT, broken_links, read_text

from cbnet_lab.doc_tables import REGION

#: The pages that state results and hold current answers only.
CURRENT_PAGES = ('README.md', 'docs/results.md', 'docs/accuracy.md',
                 'docs/benchmarks.md', 'docs/robustness.md',
                 'docs/design_readings.md',
                 'configs/cbnet/README.md', 'configs/demo/README.md',
                 'configs/pretrained/README.md',
                 'configs/baselines/README.md',
                 'configs/realfog/README.md',
                 'projects/edge_serving/README.md',
                 'projects/peer_dehaze/README.md')
JOURNAL = sorted(glob.glob(osp.join(ROOT, 'docs', 'journal', '*.md')))
#: The dated narrative that belongs to the journal.
NARRATIVE = {
    'a clock time': re.compile(r'\b\d{1,2}:\d{2}(?::\d{2})?(?:-\d{1,2}:\d{2})?'
                               r' UTC\b|\bUTC\b'),
    'a load average': re.compile(r'\bload (?:average )?(?:of )?(?:about )?'
                                 r'\d', re.I),
    'a history or status section': re.compile(
        r'^#+ .*\b(?:History|Status|[Ss]uperseded)\b', re.M),
}
#: A table cell made of figures only: ``54.2 +- 0.6``, ``0.86 / 0.85``,
#: ``**21.1**``, ``12.4x`` (a measurement has a decimal point: a bare
#: integer such as a time box of 90 s is a setting).
FIGURES = re.compile(r'^\**[-+]?\d+(?:\.\d+)?[x%]?(?: \+- \d+(?:\.\d+)?)?'
                     r'(?: / [-+]?\d+(?:\.\d+)?[x%]?(?: \+- \d+(?:\.\d+)?)?)*'
                     r'\**$')
#: ``mean +- std`` (over a line break too).
MEAN_STD = re.compile(r'(?<![\d.])(-?\d+(?:\.\d+)?)\s+\+-\s+(\d+(?:\.\d+)?)')
LINK = re.compile(r'\]\(([^)\s]+)\)')


def _read(rel):
    return read_text(osp.join(ROOT, rel))


def split_regions(text):
    """(the page without its generated regions, the regions' text)."""
    regions = [m.group('body') for m in REGION.finditer(text)]
    return REGION.sub('', text), '\n'.join(regions)


def hand_typed_table_rows(text):
    """The table rows outside generated regions and code blocks that hold
    a cell of figures only."""
    prose, _ = split_regions(FENCE.sub('', text))
    out = []
    for line in prose.splitlines():
        if not line.startswith('|') or set(line) <= set('|-: '):
            continue
        cells = [c.strip() for c in line.strip().strip('|').split('|')]
        if any(FIGURES.match(c) and '.' in c for c in cells if c):
            out.append(line)
    return out


def unbacked_figures(text):
    """The ``mean +- std`` of the prose that no generated region of the
    page holds."""
    prose, tables = split_regions(FENCE.sub('', text))
    held = {m.groups() for m in MEAN_STD.finditer(tables)}
    return sorted({f'{a} +- {b}' for a, b in MEAN_STD.findall(prose)
                   if (a, b) not in held})


@pytest.mark.parametrize('page', CURRENT_PAGES)
def test_current_pages_hold_no_dated_narrative(page):
    text, _ = split_regions(FENCE.sub('', _read(page)))
    found = [(what, m.group(0)) for what, pattern in NARRATIVE.items()
             for m in pattern.finditer(text)]
    assert not found, (f'{page} tells the story of a run: move it to '
                       f'docs/journal/ and link it: {found}')


@pytest.mark.parametrize('page', CURRENT_PAGES)
def test_every_table_of_figures_is_generated(page):
    rows = hand_typed_table_rows(_read(page))
    assert not rows, (
        f'{page}: tables of figures typed by hand (print them from their '
        'record in a <!-- table: ... --> region: '
        f'tools/misc/update_doc_tables.py): {rows[:3]}')


@pytest.mark.parametrize('page', CURRENT_PAGES)
def test_quoted_figures_are_in_the_pages_tables(page):
    missing = unbacked_figures(_read(page))
    assert not missing, (
        f'{page} quotes mean +- std figures that none of its generated '
        f'tables holds (stale, or from a table it does not show): {missing}')


@pytest.mark.parametrize('page', CURRENT_PAGES)
def test_the_journal_is_never_the_first_link(page):
    links = LINK.findall(FENCE.sub('', _read(page)))
    assert links, f'{page} links nothing'
    assert 'journal/' not in links[0], (
        f'{page} leads with the lab journal ({links[0]}): a page starts '
        'with its current answer')


def test_the_index_lists_the_journal_after_the_pages():
    links = LINK.findall(_read('docs/README.md'))
    journal = [i for i, t in enumerate(links) if t.startswith('journal/')]
    assert journal and journal[0] > links.index('results.md'), links


@pytest.mark.parametrize('page', JOURNAL, ids=lambda p: osp.relpath(p, ROOT))
def test_journal_links_resolve(page):
    bad = broken_links(page)
    assert not bad, f'{osp.relpath(page, ROOT)}: broken links: {bad}'


def test_the_checks_see_narrative_hand_tables_and_stale_figures():
    page = ('# P\n\n## History\n\nRan 06:23-06:50 UTC at load 1.4-1.8.\n\n'
            '| recipe | box AP |\n|---|---|\n| a | 54.2 +- 0.6 |\n'
            '| b | IoU 0.5/0.7/0.9 |\n\n'
            'It scores 54.2 +- 0.6 and 1.0 +-\n0.2 and 9.9 +- 0.1.\n\n'
            '<!-- table: record_table.py kernels r.json -->\n'
            '| a | 1.0 +- 0.2 |\n<!-- /table -->\n')
    found = {what for what, pattern in NARRATIVE.items()
             if pattern.search(page)}
    assert found == set(NARRATIVE)
    region = ('<!-- table: compare_recipes.py --set s --report-only -->\n'
              'ceiling from r.json (2026-11-30 03:08 UTC)\n<!-- /table -->\n')
    prose, _ = split_regions(region)
    assert not any(p.search(prose) for p in NARRATIVE.values())
    assert hand_typed_table_rows(page) == ['| a | 54.2 +- 0.6 |']
    assert unbacked_figures(page) == ['54.2 +- 0.6', '9.9 +- 0.1']
    assert FIGURES.match('**0.86 / 0.85**') and FIGURES.match('12.4x')
    assert hand_typed_table_rows('| step | box (s) |\n|---|---|\n'
                                 '| tests | 90 |\n') == []
    assert not FIGURES.match('12 epochs, 8 x 1 images')
