"""Results tables in the docs, generated from their records.

A table in a Markdown page is a marked region whose opening mark holds
the command that prints it from committed records: ``compare_recipes.py``
(the recipe comparisons), ``offload_seeds.py`` (the offload tables) or
``record_table.py`` (the speed, kernel, backbone, proposal and model-index
records that the comparison harness does not tabulate)::

    <!-- table: compare_recipes.py --set S --report-only --restore R.json -->
    ... (what the command prints: never typed by hand)
    <!-- /table -->
    <!-- table: offload_seeds.py D/seed0.json D/seed1.json D/seed2.json -->
    ...
    <!-- /table -->
    <!-- table: record_table.py kernels docs/benchmarks/kernels.json -->
    ...
    <!-- /table -->

:func:`update_docs` runs each region's command (``compare_recipes.py``
with ``--report-only``: it trains nothing; each in an output folder of
its own; every command of one update in one process, a command named by
several regions once) and writes what it prints between the marks;
``check=True`` writes nothing and names the regions that would change
(``tools/misc/update_doc_tables.py --check``, run by the tests), so no
figure in the docs goes stale.
"""
import contextlib
import glob
import io
import json
import os
import os.path as osp
import re
import runpy
import shlex
import subprocess
import sys
import tempfile
import traceback
from dataclasses import dataclass
from typing import Callable, Dict, List, Optional, Sequence, Tuple

OPEN = '<!-- table:'
CLOSE = '<!-- /table -->'
REGION = re.compile(r'<!-- table:(?P<command>.*?)-->\n(?P<body>.*?)'
                    r'<!-- /table -->', re.S)


@dataclass(frozen=True)
class Tool:
    """A command a region may name.

    Attributes:
        path (str): The script, relative to the source tree.
        out_option (str): Its option naming the output folder (given by
            :func:`render`, never by the region).
        table (str): The Markdown file it writes there.
        required (tuple[str]): Options the region must give.
    """
    path: str
    out_option: str
    table: str
    required: tuple = ()


#: The commands a region may name, by script name.
TOOLS = {
    'compare_recipes.py': Tool(
        osp.join('tools', 'analysis_tools', 'compare_recipes.py'),
        '--work-dir', 'compare.md', required=('--report-only', )),
    'offload_seeds.py': Tool(
        osp.join('projects', 'edge_serving', 'tools', 'offload_seeds.py'),
        '--out-dir', 'offload_seeds.md'),
    'record_table.py': Tool(
        osp.join('tools', 'misc', 'record_table.py'), '--out-dir',
        'record_table.md'),
}
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
        tool (str): The command's script name (a key of :data:`TOOLS`).
        argv (list[str]): The command's arguments (after the tool's name).
        body (str): What is between the marks now.
        start (int): Offset of the body in the page's text.
        end (int): Offset of the body's end.
    """
    doc: str
    line: int
    tool: str
    argv: List[str]
    body: str
    start: int
    end: int


def find_regions(text: str, doc: str = '<text>') -> List[Region]:
    """The marked regions of ``text``.

    Raises:
        ValueError: An opening mark without its closing one (or a closing
            one without an opening), or a region that names another
            command, or one without an option its command needs
            (``--report-only``: a region never trains), or one with the
            command's output folder (each region gets its own).
    """
    _check_pairs(text, doc)
    regions = []
    for m in REGION.finditer(text):
        line = text.count('\n', 0, m.start()) + 1
        words = shlex.split(m.group('command'))
        where = f'{doc}:{line}'
        name = osp.basename(words[0]) if words else None
        if name not in TOOLS:
            raise ValueError(f'{where}: a table region names '
                             f'{words[:1]}; only {", ".join(TOOLS)} '
                             'tables are generated')
        tool = TOOLS[name]
        argv = words[1:]
        for option in tool.required:
            if option not in argv:
                raise ValueError(f'{where}: the command needs {option} (a '
                                 'table is printed from its record, '
                                 'nothing is trained)')
        if tool.out_option in argv:
            raise ValueError(f'{where}: leave {tool.out_option} out (each '
                             'region is printed in a folder of its own)')
        regions.append(Region(doc=doc, line=line, tool=name, argv=argv,
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


def _env() -> dict:
    """The environment of the tools' process: the source tree and the
    projects' packages first on the path."""
    env = dict(os.environ)
    env['PYTHONPATH'] = os.pathsep.join(
        [CODE_ROOT, osp.join(CODE_ROOT, 'projects', 'peer_dehaze'),
         osp.join(CODE_ROOT, 'projects', 'edge_serving')] +
        ([env['PYTHONPATH']] if env.get('PYTHONPATH') else []))
    return env


def render_many(commands: Sequence[Tuple[str, Sequence[str]]], root: str,
                python: str = sys.executable) -> List[object]:
    """What each ``(tool, argv)`` of ``commands`` writes as its table: the
    source tree's tools (:data:`CODE_ROOT`) run one after the other in ONE
    process (the libraries are imported once), in ``root`` (where the
    records' paths start), each with an output folder of its own.

    Returns:
        list: Per command, its table (str) or a :class:`RuntimeError`
        naming the command with the tail of what it printed.
    """
    if not commands:
        return []
    with tempfile.TemporaryDirectory() as tmp:
        jobs = []
        for i, (tool, argv) in enumerate(commands):
            spec = TOOLS[tool]
            out = osp.join(tmp, str(i))
            jobs.append(dict(tool=tool, argv=list(argv),
                             script=osp.join(CODE_ROOT, spec.path),
                             out=out, out_option=spec.out_option,
                             table=osp.join(out, spec.table),
                             log=osp.join(tmp, f'{i}.log')))
        plan = osp.join(tmp, 'jobs.json')
        with open(plan, 'w') as f:
            json.dump(jobs, f)
        proc = subprocess.run(
            [python, '-m', 'cbnet_lab.doc_tables', plan], cwd=root,
            env=_env(), capture_output=True, text=True)
        results = []
        for job in jobs:
            log = ''
            if osp.isfile(job['log']):
                with open(job['log']) as f:
                    log = f.read()
            if osp.isfile(job['table']) and not log.startswith('FAILED'):
                with open(job['table']) as f:
                    results.append(f.read().strip('\n') + '\n')
                continue
            if not osp.isfile(job['log']):  # the process itself died
                log = proc.stdout + proc.stderr
            results.append(RuntimeError(
                f'{job["tool"]} {" ".join(job["argv"])} failed (exit '
                f'{proc.returncode}): {log[-2000:]}'))
        return results


def _run_jobs(plan: str) -> int:
    """Run the jobs of :func:`render_many` in this process: each tool's
    ``main(argv)`` with its output folder, what it prints kept in the
    job's log (``FAILED`` first where it raised or exited)."""
    with open(plan) as f:
        jobs = json.load(f)
    tools = {}
    for job in jobs:
        buf = io.StringIO()
        failed = False
        try:
            with contextlib.redirect_stdout(buf), \
                    contextlib.redirect_stderr(buf):
                if job['script'] not in tools:
                    tools[job['script']] = runpy.run_path(
                        job['script'], run_name='doc_tables_tool')
                tools[job['script']]['main'](
                    job['argv'] + [job['out_option'], job['out']])
        except BaseException:  # a tool's SystemExit too: report, go on
            failed = True
            buf.write(traceback.format_exc())
        with open(job['log'], 'w') as f:
            f.write(('FAILED\n' if failed else '') + buf.getvalue())
    return 0


def render(argv: Sequence[str], root: str, python: str = sys.executable,
           tool: str = 'compare_recipes.py') -> str:
    """What ``tool argv`` writes as its table (``compare.md``,
    ``offload_seeds.md``, ``record_table.md``): :func:`render_many` of one
    command.

    Raises:
        RuntimeError: The command failed (its output's tail).
    """
    (result, ) = render_many([(tool, argv)], root, python)
    if isinstance(result, Exception):
        raise result
    return result


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
                renderer: Optional[Callable] = None) -> List[Region]:
    """Regenerate every marked table of ``docs`` (default
    :func:`doc_files`).

    Args:
        root (str): The repository root (commands run there).
        docs (Sequence[str], optional): Pages, relative to ``root``.
        check (bool): Write nothing; only report.
        log (callable): Progress printer.
        renderer (callable, optional): ``(argv, root, tool=NAME) -> str``,
            one command at a time (tests); default: every command of the
            pages at once (:func:`render_many`).

    Returns:
        list[Region]: The regions whose table is (``check``: would be)
        rewritten.

    Raises:
        ValueError: A malformed mark (:func:`find_regions`).
        RuntimeError: A command failed (the page and line of its region).
    """
    docs = doc_files(root) if docs is None else list(docs)
    pages: Dict[str, Tuple[str, List[Region]]] = {}
    commands: Dict[Tuple[str, Tuple[str, ...]], object] = {}
    for doc in docs:
        with open(osp.join(root, doc)) as f:
            text = f.read()
        regions = find_regions(text, doc)
        if regions:
            pages[doc] = (text, regions)
        for region in regions:
            log(f'{doc}:{region.line}: {region.tool} '
                f'{" ".join(region.argv)}')
            commands.setdefault((region.tool, tuple(region.argv)), None)
    keys = list(commands)
    if renderer is None:
        tables = render_many([(t, list(a)) for t, a in keys], root)
    else:
        tables = [renderer(list(a), root, tool=t) for t, a in keys]
    commands.update(zip(keys, tables))
    stale = []
    for doc, (text, regions) in pages.items():
        out, last = [], 0
        for region in regions:
            table = commands[(region.tool, tuple(region.argv))]
            if isinstance(table, Exception):
                raise RuntimeError(f'{doc}:{region.line}: {table}')
            if table != region.body:
                stale.append(region)
            out += [text[last:region.start], table]
            last = region.end
        out.append(text[last:])
        new = ''.join(out)
        if new != text and not check:
            with open(osp.join(root, doc), 'w') as f:
                f.write(new)
    return stale


if __name__ == '__main__':
    sys.exit(_run_jobs(sys.argv[1]))
