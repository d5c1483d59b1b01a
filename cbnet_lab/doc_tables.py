"""Results tables in the docs, generated from their JSON records.

A table in a Markdown page is a marked region whose opening mark holds
the ``compare_recipes.py`` command that prints it from a committed
record::

    <!-- table: compare_recipes.py --set S --report-only --restore R.json -->
    ... (what the command prints: never typed by hand)
    <!-- /table -->

:func:`update_docs` runs each region's command (``--report-only``: it
trains nothing, in a work dir of its own) and writes what it prints
between the marks; ``check=True`` writes nothing and names the regions
that would change (``tools/misc/update_doc_tables.py --check``, run by
the tests), so no figure in the docs goes stale.
"""
import glob
import os
import os.path as osp
import re
import shlex
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from typing import Callable, List, Optional, Sequence

OPEN = '<!-- table:'
CLOSE = '<!-- /table -->'
REGION = re.compile(r'<!-- table:(?P<command>.*?)-->\n(?P<body>.*?)'
                    r'<!-- /table -->', re.S)
#: The one command a region may name, and the option it must have.
TOOL = 'compare_recipes.py'
TOOL_PATH = osp.join('tools', 'analysis_tools', TOOL)
#: The source tree whose tool prints the tables (this module's).
CODE_ROOT = osp.dirname(osp.dirname(osp.abspath(__file__)))
#: Pages with tables, relative to the repository root.
DOC_GLOBS = ('README.md', 'docs/**/*.md', 'configs/**/README.md',
             'projects/**/README.md')


@dataclass
class Region:
    """A marked table in a page.

    Attributes:
        doc (str): The page.
        line (int): The line of its opening mark (1-based).
        argv (list[str]): The command's arguments (after the tool's name).
        body (str): What is between the marks now.
        start (int): Offset of the body in the page's text.
        end (int): Offset of the body's end.
    """
    doc: str
    line: int
    argv: List[str]
    body: str
    start: int
    end: int


def find_regions(text: str, doc: str = '<text>') -> List[Region]:
    """The marked regions of ``text``.

    Raises:
        ValueError: An opening mark without its closing one (or a closing
            one without an opening), or a region that names another
            command, or one without ``--report-only`` (a region never
            trains), or one with ``--work-dir`` (each region gets its
            own).
    """
    _check_pairs(text, doc)
    regions = []
    for m in REGION.finditer(text):
        line = text.count('\n', 0, m.start()) + 1
        words = shlex.split(m.group('command'))
        where = f'{doc}:{line}'
        if not words or osp.basename(words[0]) != TOOL:
            raise ValueError(f'{where}: a table region names '
                             f'{words[:1]}; only {TOOL} tables are '
                             'generated')
        argv = words[1:]
        if '--report-only' not in argv:
            raise ValueError(f'{where}: the command needs --report-only '
                             '(a table is printed from its record, nothing '
                             'is trained)')
        if '--work-dir' in argv:
            raise ValueError(f'{where}: leave --work-dir out (each region '
                             'is printed in a folder of its own)')
        regions.append(Region(doc=doc, line=line, argv=argv,
                              body=m.group('body'), start=m.start('body'),
                              end=m.end('body')))
    return regions


def _check_pairs(text: str, doc: str) -> None:
    """Every opening mark is followed by its closing one before the next
    opening mark; an opening mark ends its line."""
    marks = sorted([(m.start(), OPEN) for m in re.finditer(
        re.escape(OPEN), text)] + [(m.start(), CLOSE) for m in re.finditer(
            re.escape(CLOSE), text)])
    expect = OPEN
    for pos, mark in marks + [(len(text), None)]:
        line = text.count('\n', 0, pos) + 1
        if mark is None:
            if expect == CLOSE:
                raise ValueError(f'{doc}: the last table mark is not '
                                 f'closed (no {CLOSE!r} after it)')
            return
        if mark != expect:
            what = 'a closing mark without its opening one' \
                if mark == CLOSE else 'an opening mark inside a region'
            raise ValueError(f'{doc}:{line}: {what} ({mark!r})')
        if mark == OPEN:
            tail = text[pos:].split('\n', 1)[0]
            if not tail.rstrip().endswith('-->'):
                raise ValueError(f'{doc}:{line}: a table mark is one line: '
                                 f'{OPEN} COMMAND -->')
        expect = CLOSE if mark == OPEN else OPEN


def render(argv: Sequence[str], root: str, python: str = sys.executable
           ) -> str:
    """What ``compare_recipes.py argv`` prints as its tables
    (``compare.md``): the source tree's tool (:data:`CODE_ROOT`), run in
    ``root`` (where the records' paths start) with a work dir of its own.

    Raises:
        RuntimeError: The command failed (its output's tail).
    """
    with tempfile.TemporaryDirectory() as tmp:
        env = dict(os.environ)
        env['PYTHONPATH'] = os.pathsep.join(
            [CODE_ROOT, osp.join(CODE_ROOT, 'projects', 'peer_dehaze')] +
            ([env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
        proc = subprocess.run(
            [python, osp.join(CODE_ROOT, TOOL_PATH), *argv, '--work-dir',
             tmp],
            cwd=root, env=env, capture_output=True, text=True)
        table = osp.join(tmp, 'compare.md')
        if proc.returncode != 0 or not osp.isfile(table):
            raise RuntimeError(
                f'{TOOL} {" ".join(argv)} failed (exit {proc.returncode}): '
                f'{(proc.stdout + proc.stderr)[-2000:]}')
        with open(table) as f:
            return f.read().strip('\n') + '\n'


def doc_files(root: str) -> List[str]:
    """Every page of :data:`DOC_GLOBS` under ``root`` (sorted, relative)."""
    found = set()
    for pattern in DOC_GLOBS:
        for path in glob.glob(osp.join(root, pattern), recursive=True):
            rel = osp.relpath(path, root)
            if not rel.startswith(('.', 'work_dirs', 'data')):
                found.add(rel)
    return sorted(found)


def update_docs(root: str, docs: Optional[Sequence[str]] = None,
                check: bool = False, log: Callable = print,
                renderer: Callable = render) -> List[Region]:
    """Regenerate every marked table of ``docs`` (default
    :func:`doc_files`).

    Args:
        root (str): The repository root (commands run there).
        docs (Sequence[str], optional): Pages, relative to ``root``.
        check (bool): Write nothing; only report.
        log (callable): Progress printer.
        renderer (callable): ``(argv, root) -> str`` (tests).

    Returns:
        list[Region]: The regions whose table is (``check``: would be)
        rewritten.
    """
    stale = []
    docs = doc_files(root) if docs is None else list(docs)
    for doc in docs:
        path = osp.join(root, doc)
        with open(path) as f:
            text = f.read()
        regions = find_regions(text, doc)
        if not regions:
            continue
        out, last = [], 0
        for region in regions:
            log(f'{doc}:{region.line}: {TOOL} {" ".join(region.argv)}')
            table = renderer(region.argv, root)
            if table != region.body:
                stale.append(region)
            out += [text[last:region.start], table]
            last = region.end
        out.append(text[last:])
        new = ''.join(out)
        if new != text and not check:
            with open(path, 'w') as f:
                f.write(new)
    return stale
