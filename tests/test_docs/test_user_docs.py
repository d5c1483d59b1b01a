"""What a user reads stays readable and points where it says:

* the README is short (at most :data:`README_MAX_LINES` lines);
* docs/README.md, the index, names every page of docs/ and every
  project's README;
* no page a user reads (README, docs/*.md, projects/*/README.md) carries
  the development history's issue numbers or the development machines'
  paths;
* no tracked text file of the repository (code, configs, tests, shell
  scripts, every markdown file) carries an issue number either;
* every relative link of those pages reaches an existing file and, where
  it names one, an existing heading of a markdown file (GitHub's anchor of
  the heading);
* every page of docs/ and every project's README starts with its current
  answer ("In short");
* every registered name of the README's components table is in an MMDet
  registry once the plugin is imported, and every file it names exists;
* every figure of the README's results table is one that its row's linked
  JSON record gives (a seed mean or std, a ratio of median times, or a
  value it holds), and a row without a record quotes none.
"""
import glob
import json
import os
import os.path as osp
import re
import statistics
import subprocess

import pytest
from doc_helpers import LINK, ROOT, anchors, broken_links, read_text
from record_helpers import seed_values

README_MAX_LINES = 230
#: An issue of the development history: ``issue 42``, ``issues 23``,
#: ``#23`` (not inside a link's anchor), an anchor ``...-issue-42``.
ISSUE_REF = re.compile(r'\bissues? \d+|(?<![\w#/&])#\d+\b', flags=re.I)
#: The anchor of a heading that named an issue.
ISSUE_ANCHOR = re.compile(r'-issue-\d+\b', flags=re.I)
#: Paths of the machines the project is developed on.
DEV_PATH = re.compile(r'/work/|\.\./shared\b|\bshared/data\b')
#: An issue in code, configs and scripts, where ``#1`` is a list marker or a
#: comment and ``#000000`` a colour: ``issue 42``, ``issues #23``.
CODE_ISSUE_REF = re.compile(r'\bissues? #?\d+', flags=re.I)
#: The text files of the repository that the issue check reads (JSON
#: records are data, not prose).
TEXT_SUFFIXES = ('.py', '.sh', '.md', '.yml', '.yaml', '.cfg', '.toml',
                 '.txt')
#: Folders a walk of the tree skips where git cannot list the files.
UNTRACKED_DIRS = frozenset(
    {'.git', '.venv', 'work_dirs', 'data', '__pycache__'})
#: This file, whose checks quote what they forbid.
THIS_FILE = osp.abspath(__file__)


def user_pages(root=ROOT):
    """README.md, docs/*.md (the index included) and the projects'
    READMEs, as paths."""
    return [osp.join(root, 'README.md')] + sorted(
        glob.glob(osp.join(root, 'docs', '*.md')) +
        glob.glob(osp.join(root, 'projects', '*', 'README.md')))


def _rel(path, root=ROOT):
    return osp.relpath(path, root)


def _issues_in_line(line, markdown=True):
    """The issue references of one line: in markdown, :data:`ISSUE_REF`
    outside link targets and :data:`ISSUE_ANCHOR`; elsewhere
    :data:`CODE_ISSUE_REF` and :data:`ISSUE_ANCHOR`."""
    if markdown:
        # a link's target is a file or an anchor (``](#3-seeds)``), not
        # prose: only a stale issue anchor or a machine path counts there
        refs = ISSUE_REF.finditer(LINK.sub('](link)', line))
    else:
        refs = CODE_ISSUE_REF.finditer(line)
    return [m.group(0) for m in refs] + \
        [m.group(0) for m in ISSUE_ANCHOR.finditer(line)]


def forbidden_mentions(text):
    """(line number, text) of each issue reference or development-machine
    path outside link targets' anchors."""
    out = []
    for number, line in enumerate(text.splitlines(), 1):
        out += [(number, m) for m in _issues_in_line(line)]
        out += [(number, m.group(0)) for m in DEV_PATH.finditer(line)]
    return out


def issue_mentions(text, markdown=True):
    """(line number, text) of each issue reference of a file's text (the
    markdown check of :func:`forbidden_mentions` less the machine paths,
    or the code check where ``markdown`` is false)."""
    return [(number, m)
            for number, line in enumerate(text.splitlines(), 1)
            for m in _issues_in_line(line, markdown)]


def _walk_text_files(root):
    """The text files under ``root`` (relative paths), the folders of
    :data:`UNTRACKED_DIRS` skipped."""
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if d not in UNTRACKED_DIRS)
        out += [
            _rel(osp.join(dirpath, name), root) for name in sorted(filenames)
        ]
    return out


def repository_text_files(root=ROOT):
    """Every text file of the repository as a path: what ``git ls-files``
    lists (the whole tree, :data:`UNTRACKED_DIRS` skipped, where git is
    missing or lists nothing) with a suffix of :data:`TEXT_SUFFIXES`;
    links (their targets are listed themselves) and files that are not
    UTF-8 text are left out."""
    try:
        listed = subprocess.run(['git', 'ls-files', '-z'],
                                cwd=root,
                                capture_output=True,
                                check=True).stdout.decode('utf-8')
        paths = [p for p in listed.split('\0') if p]
    except (OSError, subprocess.CalledProcessError):
        paths = []
    if not paths:
        paths = _walk_text_files(root)
    out = []
    for path in sorted(paths):
        full = osp.join(root, path)
        if not path.endswith(TEXT_SUFFIXES) or osp.islink(full) or \
                not osp.isfile(full):
            continue
        with open(full, 'rb') as f:
            data = f.read()
        try:
            if b'\0' not in data:
                data.decode('utf-8')
                out.append(full)
        except UnicodeDecodeError:
            pass
    return out


def test_readme_is_short():
    lines = read_text(osp.join(ROOT, 'README.md')).splitlines()
    assert len(lines) <= README_MAX_LINES, (
        f'README.md has {len(lines)} lines (at most {README_MAX_LINES}): '
        'move detail to docs/ and link it')


def test_docs_index_names_every_page():
    index = osp.join(ROOT, 'docs', 'README.md')
    targets = {
        osp.normpath(osp.join(osp.dirname(index),
                              t.split('#')[0]))
        for t in LINK.findall(read_text(index))
    }
    pages = [p for p in user_pages() if p != index and _rel(p) != 'README.md']
    missing = [_rel(p) for p in pages if p not in targets]
    assert not missing, f'docs/README.md does not list: {missing}'


@pytest.mark.parametrize('page', user_pages(), ids=_rel)
def test_no_issue_numbers_or_machine_paths(page):
    found = forbidden_mentions(read_text(page))
    assert not found, (f'{_rel(page)} names the development history or '
                       f'machines (line, text): {found}')


def test_no_issue_numbers_in_any_text_file():
    """Code, configs, tests, shell scripts and every markdown file name no
    issue of the development history either (this file aside: its checks
    quote what they forbid)."""
    files = repository_text_files()
    assert osp.join(ROOT, 'README.md') in files, files[:5]
    found = {}
    for path in files:
        if path == THIS_FILE:
            continue
        mentions = issue_mentions(read_text(path),
                                  markdown=path.endswith('.md'))
        if mentions:
            found[_rel(path)] = mentions
    assert not found, ('files that name issues of the development history '
                       f'(file: [(line, text)]): {found}')


def test_the_issue_checks_of_code_spare_code(tmp_path):
    """In code the check finds issue numbers and issue anchors, not
    colours, list markers or ``#1`` comments; markdown keeps its own
    check; the walk of the tree skips virtual environments, data and work
    folders, and the lister skips JSON records and binary files."""
    code = ("color='#000000'  # 1) first\n"
            "#1 list marker; x#2\n"
            "# see issue 42 and Issues #7\n"
            "url = 'docs/a.md#real-fog-issue-3'\n")
    assert issue_mentions(code, markdown=False) == [(3, 'issue 42'),
                                                    (3, 'Issues #7'),
                                                    (4, '-issue-3')]
    assert issue_mentions('a list (#23) and issue 5', markdown=True) == [
        (1, '#23'), (1, 'issue 5')
    ]
    for folder in ('.venv', 'data', 'work_dirs', 'pkg'):
        (tmp_path / folder).mkdir()
        (tmp_path / folder / 'a.py').write_text('# issue 1\n')
    (tmp_path / 'pkg' / 'r.json').write_text('{"note": "issue 2"}')
    (tmp_path / 'pkg' / 'b.txt').write_bytes(b'\x89PNG\0issue 3')
    assert _walk_text_files(str(tmp_path)) == [
        osp.join('pkg', 'a.py'),
        osp.join('pkg', 'b.txt'),
        osp.join('pkg', 'r.json')
    ]
    # not a git work tree, or one that tracks none of it: walked
    assert repository_text_files(str(tmp_path)) == [
        str(tmp_path / 'pkg' / 'a.py')
    ]


@pytest.mark.parametrize('page', user_pages(), ids=_rel)
def test_relative_links_resolve(page):
    bad = broken_links(page)
    assert not bad, f'{_rel(page)}: broken links: {bad}'


def test_the_checks_see_what_they_should(tmp_path):
    """The checkers themselves, on a small tree: a missing file, a missing
    anchor, a link outside the tree, issue numbers and machine paths are
    found; a good link, a heading's anchor and a heading inside a code
    block (not an anchor) are told apart."""
    docs = tmp_path / 'docs'
    docs.mkdir()
    (docs / 'a.md').write_text(
        '# Page A\n\n## Real fog on a trunk (`realfog`), 3 seeds\n\n'
        '## Same\n\n## Same\n\n```bash\n# not a heading\n```\n'
        '<a name="status-2026-11-27"></a>\n')
    page = docs / 'b.md'
    page.write_text(
        '[ok](a.md#real-fog-on-a-trunk-realfog-3-seeds) [ok2](a.md#same-1)'
        ' [self](#b) [missing](nope.md) [anchor](a.md#not-a-heading)'
        ' [out](../../x.md) [web](https://example.org/#3)\n\n# B\n'
        'As issue 42 asks (#23), see /work/main and ../shared/data;'
        ' [x](a.md#page-a) and a colour &#38;.\n')
    assert anchors(str(docs / 'a.md')) == {
        'page-a', 'real-fog-on-a-trunk-realfog-3-seeds', 'same', 'same-1',
        'status-2026-11-27'
    }
    bad = dict(broken_links(str(page), root=str(tmp_path)))
    assert set(bad) == {'nope.md', 'a.md#not-a-heading', '../../x.md'}
    assert 'outside' in bad['../../x.md']
    found = [m for _, m in forbidden_mentions(page.read_text())]
    assert found == ['issue 42', '#23', '/work/', '../shared']
    assert forbidden_mentions('[a](b.md#c) and &#38; and x#1') == []
    assert forbidden_mentions('anchor (x.md#real-fog-issue-42)') == [
        (1, '-issue-42')
    ]


@pytest.mark.parametrize(
    'page', [
        p for p in user_pages()
        if _rel(p) not in ('README.md', osp.join('docs', 'README.md'))
    ],
    ids=_rel)
def test_page_starts_with_its_answer(page):
    """Below its title, every page of docs/ and every project's README
    starts with its current answer: an "In short" paragraph or section."""
    lines = [line for line in read_text(page).splitlines()[1:] if line.strip()]
    assert lines and lines[0].startswith(('In short', '## In short')), (
        f'{_rel(page)} does not start with "In short" under its title: '
        f'{lines[:1]}')


def readme_components():
    """(registered names, files) of each row of the README's components
    table; files are relative to ``cbnet_mmdet/``."""
    text = read_text(osp.join(ROOT, 'README.md'))
    section = text.split('\n## Components\n', 1)[1].split('\n## ', 1)[0]
    lines = [line for line in section.splitlines() if line.startswith('|')]
    rows = [line.split(' | ') for line in lines[2:]]  # after the header
    return [(re.findall(r'`([^`]+)`',
                        row[1]), re.findall(r'`([^`]+)`', row[2]))
            for row in rows]


def test_readme_components_are_registered_where_it_says():
    from mmdet.registry import DATASETS, HOOKS, METRICS, MODELS

    import cbnet_mmdet  # noqa: F401
    rows = readme_components()
    assert len(rows) >= 8, rows
    for names, files in rows:
        assert names and files, (names, files)
        for name in names:
            assert any(name in registry.module_dict
                       for registry in (MODELS, DATASETS, METRICS, HOOKS)), \
                f'README names {name}, which no MMDet registry holds'
        for path in files:
            assert osp.exists(osp.join(ROOT, 'cbnet_mmdet', path)), \
                f'README: cbnet_mmdet/{path} does not exist'


def record_numbers(record):
    """Every figure a table may quote from a JSON record, computed here
    from its raw content (not from a summary the record may also hold):
    its numeric leaves; for a comparison record (``runs`` of ``recipe`` /
    ``seed`` / ``metrics``) the mean and sample std over seeds, in percent,
    of each recipe's metric under each condition; for a benchmark record
    (``inference_round_times_s``) the ratio of the median round times of
    any two models of one cell."""
    out = []

    def leaves(obj):
        if isinstance(obj, dict):
            for value in obj.values():
                leaves(value)
        elif isinstance(obj, list):
            for value in obj:
                leaves(value)
        elif isinstance(obj, (int, float)) and not isinstance(obj, bool):
            out.append(float(obj))

    leaves(record)
    for values in seed_values(record).values():
        values = [v for _, v in values]
        mean = sum(values) / len(values)
        out.append(mean)
        if len(values) > 1:
            out.append((sum(
                (v - mean)**2 for v in values) / (len(values) - 1))**0.5)
    for cell in (record.get('inference_round_times_s') or {}).values():
        medians = [statistics.median(t) for t in cell.values()]
        out += [a / b for a in medians for b in medians]
    return out


def quoted_numbers(cell):
    """The decimal figures of a table cell, with their precision."""
    return [(float(m), len(m.split('.')[1]))
            for m in re.findall(r'\d+\.\d+', cell)]


def readme_results_rows():
    """(row, figure cells, linked records) of the README's results
    table."""
    text = read_text(osp.join(ROOT, 'README.md'))
    section = text.split('\n## Results\n', 1)[1].split('\n## ', 1)[0]
    lines = [line for line in section.splitlines() if line.startswith('|')]
    out = []
    for line in lines[2:]:
        cells = [c.strip() for c in line.strip('|').split(' | ')]
        records = [
            osp.join(ROOT, t) for t in LINK.findall(cells[-1])
            if t.endswith('.json')
        ]
        out.append((cells[0], cells[2:-1], records))
    return out


def test_readme_results_are_their_records():
    """Every figure of the README's results table is one its row's JSON
    record gives (to the precision quoted); a row without a record quotes
    no figure ("being measured")."""
    rows = readme_results_rows()
    assert len(rows) >= 4, rows
    for name, cells, records in rows:
        quoted = [q for cell in cells for q in quoted_numbers(cell)]
        if not records:
            assert not quoted, f'README results: {name!r} quotes ' \
                f'{quoted} without a record'
            continue
        derived = []
        for path in records:
            with open(path, encoding='utf-8') as f:
                derived += record_numbers(json.load(f))
        wrong = [
            value for value, digits in quoted if not any(
                abs(d - value) <= 0.5 * 10**-digits + 1e-9 for d in derived)
        ]
        assert not wrong, (f'README results: {name!r} quotes {wrong}, '
                           f'which {records} do not give')


def test_record_numbers_derive_means_and_ratios():
    record = dict(
        runs=[
            dict(recipe='a', seed=s, metrics=dict(clear={'m': v}))
            for s, v in enumerate((0.340, 0.325, 0.353))
        ],
        inference_round_times_s=dict(
            cell=dict(x=[6.0, 6.2, 9.0], y=[3.0, 3.1, 2.0])))
    got = record_numbers(record)
    assert any(abs(v - 33.93) < 0.01 for v in got)  # mean, percent
    assert any(abs(v - 1.40) < 0.01 for v in got)  # sample std
    assert any(abs(v - 6.2 / 3.0) < 1e-9 for v in got)  # medians' ratio
    assert quoted_numbers('**9.5 / 20.7** (x) 1.00') == [(9.5, 1), (20.7, 1),
                                                         (1.0, 2)]
