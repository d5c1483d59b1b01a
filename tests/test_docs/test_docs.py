"""The docs' own commands, snippets and file references.

* every repository file a doc cites (in backticks or as a link) exists in
  the repository: no doc points outside it or at a file we do not ship;
* every documented ``python tools/...`` (or ``python projects/NAME/tools/
  ...``) command line is accepted by that tool's argument parser, and the
  ``tools/train.py`` ones build their config and visualiser (the
  TensorBoard command of docs/visualization.md once passed its backends
  as strings);
* the README's "single components" snippet builds under MMDetection's
  stock Mask R-CNN through ``_base_`` inheritance, as a user would use it.
"""
import argparse
import glob
import inspect
import os.path as osp
import re
import shlex
import sys

import pytest
import torch
from mmengine.config import Config
from mmengine.registry import init_default_scope
from doc_helpers import ROOT, read_text, readme_snippet
from tool_helpers import load_tool, tool_file

#: The config families' READMEs whose commands and citations are checked.
FAMILY_READMES = [osp.join(ROOT, 'configs', family, 'README.md')
                  for family in ('baselines', 'cbnet', 'coco_trunk', 'demo',
                                 'pretrained', 'realfog', 'yolox_coco')]
DOCS = [osp.join(ROOT, 'README.md')] + sorted(
    glob.glob(osp.join(ROOT, 'docs', '**', '*.md'), recursive=True) +
    FAMILY_READMES +
    glob.glob(osp.join(ROOT, 'projects', '*', 'README.md')))
#: Top-level folders of the repository a citation may start with.
REPO_DIRS = ('cbnet_mmdet/', 'cbnet_lab/', 'cbnet_tools/', 'configs/',
             'tools/', 'tests/', 'docs/', 'requirements/', '.ci/',
             'projects/')
#: What the README snippet must be built on.
STOCK_MASK_RCNN = 'mmdet::mask_rcnn/mask-rcnn_r50_fpn_1x_coco.py'


def _rel(path):
    return osp.relpath(path, ROOT)


def _expand_braces(pattern):
    """``a{0..2}b`` / ``a{x,y}b`` -> every expansion (shell-like)."""
    match = re.search(r'\{([^{}]*)\}', pattern)
    if match is None:
        return [pattern]
    body = match.group(1)
    span = re.fullmatch(r'(\d+)\.\.(\d+)', body)
    items = ([str(i) for i in range(int(span[1]), int(span[2]) + 1)]
             if span else body.split(','))
    out = []
    for item in items:
        out += _expand_braces(pattern[:match.start()] + item +
                              pattern[match.end():])
    return out


def cited_paths(doc):
    """(citation, paths it names) for each file path the doc cites.

    Citations are backticked words and link targets that start with a
    repository folder (``configs/``, ``tools/`` ...), with ``papers/`` or
    are absolute; link targets are relative to the doc. Placeholders
    (``<...>``, ``...``) are skipped; ``{a,b}``/``{0..5}`` and ``*`` are
    expanded.
    """
    text = read_text(doc)
    doc_dir = osp.dirname(doc)
    candidates = []
    for code in re.findall(r'`([^`\n]+)`', text):
        word = code.split()[0] if code.split() else ''
        candidates.append((code, word, ROOT, False))
    for target in re.findall(r'\]\(([^)\s]+)\)', text):
        if '://' in target or target.startswith(('#', 'mailto:')):
            continue
        candidates.append((target, target.split('#')[0], doc_dir, True))
    for citation, word, base, link in candidates:
        word = word.split('::')[0].rstrip('.,;:)')
        in_repo = link or word.startswith(REPO_DIRS)
        outside = word.startswith(('/', 'papers/', '~'))
        if not (in_repo or outside) or not word:
            continue
        if '<' in word or '...' in word or '$' in word:
            continue
        paths = []
        for expanded in _expand_braces(word):
            full = osp.normpath(osp.join(base, expanded))
            paths.append(full)
        yield citation, paths


def _exists(path):
    return bool(glob.glob(path)) if '*' in path else osp.exists(path)


@pytest.mark.parametrize('doc', DOCS, ids=_rel)
def test_cited_files_exist_in_the_repository(doc):
    bad = []
    for citation, paths in cited_paths(doc):
        for path in paths:
            inside = (path + '/').startswith(ROOT + '/')
            if not inside or not _exists(path):
                bad.append(f'`{citation}` -> {path}' +
                           ('' if inside else ' (outside the repository)'))
    assert not bad, f'{_rel(doc)} cites files the repository lacks:\n' + \
        '\n'.join(bad)


def test_the_citation_scanner_sees_outside_and_missing_files(tmp_path):
    """The scanner itself: an outside path, a missing repository file and
    a missing link are reported; existing ones are not."""
    doc = tmp_path / 'doc.md'
    doc.write_text('see `/work/shared/papers/x.txt`, `papers/y.txt`, '
                   '`tools/train.py`, `configs/nope.py`, '
                   '`configs/cbnet/cbnet_mit-b{0..1}_nasfpn-crpn_8xb1-12e'
                   '_cityscapes.py` and [a](missing.png)\n')
    found = {c: p for c, p in cited_paths(str(doc))}
    assert set(found) == {
        '/work/shared/papers/x.txt', 'papers/y.txt', 'tools/train.py',
        'configs/nope.py', 'missing.png',
        'configs/cbnet/cbnet_mit-b{0..1}_nasfpn-crpn_8xb1-12e_cityscapes.py'
    }
    assert len(found['configs/cbnet/cbnet_mit-b{0..1}_nasfpn-crpn_8xb1-12e'
                     '_cityscapes.py']) == 2
    assert not _exists(found['configs/nope.py'][0])
    assert _exists(found['tools/train.py'][0])


#: A fenced ``bash``/``shell``/``sh`` block; group 1 is its text.
BASH_BLOCK = re.compile(r'```(?:bash|shell|sh)\n(.*?)```', flags=re.S)


def bash_blocks(doc):
    """The fenced ``bash``/``shell``/``sh`` blocks of a markdown file."""
    return BASH_BLOCK.findall(read_text(doc))


#: Placeholders of documented command lines that a parser checks.
PLACEHOLDERS = {
    'H': '64', 'W': '128',
    'CONFIG': osp.join(ROOT, 'configs', 'demo',
                       'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
}


def tool_commands():
    """(doc, tool path under tools/, argv) of every documented
    ``python tools/X.py ...`` command (a project's, ``python
    projects/NAME/tools/X.py``, keeps its path from the repository root,
    as ``tool_helpers.load_tool`` takes it). Optional parts written ``[...]``
    are included, without their brackets; of alternatives ``a|b`` the
    first; loop variables and :data:`PLACEHOLDERS` get a value."""
    return [(_rel(doc), tool, argv) for doc in DOCS
            for block in bash_blocks(doc)
            for tool, argv in block_commands(block)]


def block_commands(block):
    """(tool path under tools/, argv) of each ``python tools/X.py ...``
    command of one bash block, as :func:`tool_commands` reads them."""
    out = []
    # a loop variable stands for the loop's first value
    for var, values in re.findall(r'for (\w+) in ([^;\n]+); do', block):
        block = block.replace(f'${var}', values.split()[0])
    for line in block.replace('\\\n', ' ').splitlines():
        try:
            words = shlex.split(line, comments=True)
        except ValueError:
            continue
        for i, word in enumerate(words[:-1]):
            script = words[i + 1]
            if word in ('python', 'python3') and \
                    re.match(r'(projects/[^/]+/)?tools/', script) \
                    and script.endswith('.py'):
                argv = []
                for arg in words[i + 2:]:
                    if arg in ('&&', '&', '|', ';', '>'):
                        break
                    # `a|b`: one of the alternatives
                    arg = arg.strip('[]').split('|')[0]
                    arg = PLACEHOLDERS.get(arg, arg)
                    if arg and arg != '...':
                        argv.append(arg)
                if script.startswith('tools/'):
                    script = script[len('tools/'):]
                out.append((script, argv))
    return out


COMMANDS = tool_commands()


def test_docs_document_tool_commands():
    tools = {tool for _, tool, _ in COMMANDS}
    # the scanner finds the commands of the main tools
    assert {'train.py', 'test.py', 'analysis_tools/ap_drop.py',
            'model_converters/extract_student.py',
            'projects/peer_dehaze/tools/train_dehazer.py',
            'projects/edge_serving/tools/serve.py',
            'projects/edge_serving/tools/route.py'} <= tools, tools


@pytest.mark.parametrize(
    'doc,tool,argv', COMMANDS,
    ids=[f'{d}:{t}:{i}' for i, (d, t, _) in enumerate(COMMANDS)])
def test_documented_command_parses(doc, tool, argv, restore_environ,
                                   monkeypatch):
    assert osp.isfile(tool_file(tool)), \
        f'{doc} documents {_rel(tool_file(tool))}, which does not exist'
    module = load_tool(tool)
    # the parser reads sys.argv where parse_args takes no argv
    monkeypatch.setattr(sys, 'argv', [f'tools/{tool}'] + argv)
    takes_argv = bool(inspect.signature(module.parse_args).parameters)
    parsers = []
    parse = argparse.ArgumentParser.parse_args

    def recording(parser, *args, **kwargs):
        parsers.append(parser)
        return parse(parser, *args, **kwargs)

    monkeypatch.setattr(argparse.ArgumentParser, 'parse_args', recording)
    try:
        args = module.parse_args(argv) if takes_argv else module.parse_args()
    except SystemExit as err:
        raise AssertionError(
            f'{doc}: `python tools/{tool} {" ".join(argv)}` is refused by '
            f'the tool\'s arguments') from err
    assert parsers, f'{tool}: parse_args parsed nothing'
    wrong = misparsed(parsers[-1], args, argv)
    assert not wrong, (f'{doc}: `python tools/{tool} {" ".join(argv)}`: '
                       f'(argument, documented, parsed): {wrong}')


def misparsed(parser, args, argv):
    """(argument, documented value, parsed value) of every plain argument
    of ``argv`` (a positional or an option storing one value, or a flag)
    whose value in the parsed ``args`` is not the documented one."""
    options = {s: a for a in parser._actions for s in a.option_strings}
    positionals = [a for a in parser._actions
                   if not a.option_strings and a.nargs is None]
    checks, loose, i = [], [], 0
    while i < len(argv):
        word = argv[i]
        name, _, inline = word.partition('=')
        action = options.get(name) if word.startswith('-') else None
        if action is None:
            if not word.startswith('-'):
                loose.append(word)
            i += 1
        elif action.nargs == 0:  # a flag: its constant
            checks.append((name, action, action.const, False))
            i += 1
        elif action.nargs is None:  # one value
            value = inline if inline else argv[i + 1] if \
                i + 1 < len(argv) else None
            checks.append((name, action, value, True))
            i += 1 if inline else 2
        elif action.nargs == '?':  # an optional value: not checked
            i += 1 if inline or i + 1 == len(argv) or \
                argv[i + 1].startswith('-') else 2
        else:  # a list: its values are not checked one by one
            i += 1
            while i < len(argv) and not argv[i].startswith('--'):
                i += 1
    checks += [(a.dest, a, word, True) for a, word in zip(positionals, loose)]
    wrong = []
    for name, action, value, convert in checks:
        if type(action).__name__ not in ('_StoreAction', '_StoreTrueAction',
                                         '_StoreFalseAction',
                                         '_StoreConstAction'):
            continue  # a custom action (DictAction...) keeps its own form
        expected = (action.type or str)(value) if convert else value
        if getattr(args, action.dest) != expected:
            wrong.append((name, expected, getattr(args, action.dest)))
    return wrong


#: The opening mark of a generated table (cbnet_lab/doc_tables.py).
OPEN_MARK = '<!-- table:'


def tabulated_records():
    """(doc, argv, table rows) of every documented ``compare_recipes.py
    --report-only`` command not right above a generated region: the ``|``
    and ``Left out`` lines after its bash block, up to the next block or
    heading (a table typed by hand)."""
    out = []
    for doc in DOCS:
        text = read_text(doc)
        for m in BASH_BLOCK.finditer(text):
            if text[m.end():].lstrip().startswith(OPEN_MARK):
                continue
            after = re.split(r'\n```|\n#', text[m.end():])[0]
            rows = [line.strip() for line in after.splitlines()
                    if line.startswith(('|', 'Left out'))]
            for tool, argv in block_commands(m.group(1)):
                if tool.endswith('compare_recipes.py') and \
                        '--report-only' in argv:
                    out.append((_rel(doc), argv, rows))
    return out


TABULATED = tabulated_records()


def shown_region_commands():
    """(doc, line, the region's command, the commands of the bash block
    right above it) of every generated region a bash block shows: the
    block ends where the region's opening mark starts (blank lines aside).
    A command is ``(script name, argv)``; ``--work-dir`` and ``--out-dir``
    (the region's tool gives its own) are left out."""
    from cbnet_lab.doc_tables import find_regions
    out = []
    for doc in DOCS:
        text = read_text(doc)
        blocks = list(BASH_BLOCK.finditer(text))
        for region in find_regions(text, _rel(doc)):
            mark = text.rfind(OPEN_MARK, 0, region.start)
            above = [b for b in blocks
                     if b.end() <= mark and not text[b.end():mark].strip()]
            if not above:
                continue
            shown = []
            for tool, argv in block_commands(above[-1].group(1)):
                for option in ('--work-dir', '--out-dir'):
                    if option in argv:
                        i = argv.index(option)
                        argv = argv[:i] + argv[i + 2:]
                shown.append((osp.basename(tool), argv))
            out.append((_rel(doc), region.line,
                        (region.tool, region.argv), shown))
    return out


SHOWN = shown_region_commands()


def test_docs_tabulate_a_record():
    # the old form (a table pasted under its command, checked here) or a
    # generated region under the command that prints it
    assert any(doc == 'docs/accuracy.md' for doc, _, _, _ in SHOWN)
    assert {tool for _, _, (tool, _), _ in SHOWN} >= {
        'compare_recipes.py', 'record_table.py'}


@pytest.mark.parametrize('doc,line,command,shown', SHOWN,
                         ids=[f'{d}:{n}' for d, n, _, _ in SHOWN])
def test_a_command_shown_above_a_table_is_the_one_that_prints_it(
        doc, line, command, shown):
    """The bash block right above a generated table shows the command
    that prints it (the region's own), so a reader can run what made it."""
    assert command in shown, (
        f'{doc}:{line}: the table is printed by {command}; the block above '
        f'it shows {shown}')


def test_no_table_is_pasted_under_a_report_only_command():
    """Every documented ``compare_recipes.py --report-only`` command sits
    right above the generated table it prints (checked against the record
    by test_generated_tables_are_what_their_records_print); a table typed
    under one instead goes stale unseen."""
    assert not TABULATED, (
        'tables pasted under a --report-only command (make each a '
        'generated region: tools/misc/update_doc_tables.py): ' +
        ', '.join(f'{doc}: compare_recipes.py {" ".join(argv)}'
                  for doc, argv, _ in TABULATED))


TRAIN_COMMANDS = [(d, argv) for d, t, argv in COMMANDS
                  if t == 'train.py' and argv and
                  osp.isfile(osp.join(ROOT, argv[0]))]


@pytest.mark.parametrize('doc,argv', TRAIN_COMMANDS,
                         ids=[f'{d}:{i}'
                              for i, (d, _) in enumerate(TRAIN_COMMANDS)])
def test_documented_train_command_builds_config_and_visualizer(
        doc, argv, tmp_path, restore_environ):
    from mmengine.registry import VISUALIZERS
    train = load_tool('train.py')
    cfg = train.build_cfg(train.parse_args(argv))
    init_default_scope(cfg.get('default_scope', 'mmdet'))
    vis_cfg = dict(cfg.visualizer)
    vis_cfg.update(name=f'doc_vis_{tmp_path.name}', save_dir=str(tmp_path))
    visualizer = VISUALIZERS.build(vis_cfg)
    assert type(visualizer).__name__ == vis_cfg['type'].split('.')[-1]
    # every backend the config (with the command's options) names is there
    backends = vis_cfg.get('vis_backends') or []
    assert backends, f'{doc}: the config names no visualisation backend'
    for backend in backends:
        name = backend.get('name', backend['type'])
        built = visualizer.get_backend(name)
        assert type(built).__name__ == backend['type'].split('.')[-1], name


def test_visualization_doc_tensorboard_command(tmp_path, restore_environ):
    """docs/visualization.md's command line adds TensorBoard."""
    (argv, ) = [a for d, t, a in COMMANDS
                if d == 'docs/visualization.md' and t == 'train.py']
    train = load_tool('train.py')
    cfg = train.build_cfg(train.parse_args(argv))
    types = [b['type'] for b in cfg.visualizer.vis_backends]
    assert types == ['LocalVisBackend', 'TensorboardVisBackend']
    # twice is once
    train.add_tensorboard_backend(cfg)
    assert len(cfg.visualizer.vis_backends) == 2


def test_readme_snippet_builds_on_mmdet_stock_mask_rcnn(tmp_path):
    snippet = readme_snippet()
    if '_base_' not in snippet:  # as a user puts it under a stock config
        snippet = f'_base_ = {STOCK_MASK_RCNN!r}\n' + snippet
    assert STOCK_MASK_RCNN in snippet
    # the snippet's `ann_file=...` placeholders
    snippet = snippet.replace('ann_file=...', "ann_file='ann.json'")
    path = tmp_path / 'my_mask_rcnn.py'
    path.write_text(snippet)
    cfg = Config.fromfile(str(path))
    assert cfg.model.roi_head.mask_head.loss_mask == dict(
        type='CBNetBoundaryAwareLoss', lambda_shape=1.0, lambda_edge=1.0)
    from mmdet.registry import MODELS
    init_default_scope('mmdet')
    # a small ResNet-18 with 16 channels everywhere, for speed
    model_cfg = cfg.model
    model_cfg.backbone.update(depth=18, base_channels=8, init_cfg=None)
    model_cfg.neck.update(in_channels=[8, 16, 32, 64], out_channels=16)
    model_cfg.rpn_head.update(in_channels=16, feat_channels=16)
    for key in ('bbox_roi_extractor', 'mask_roi_extractor'):
        model_cfg.roi_head[key].out_channels = 16
    for key in ('bbox_head', 'mask_head'):
        model_cfg.roi_head[key].in_channels = 16
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()
    assert type(model.roi_head.mask_head.loss_mask).__name__ == \
        'CBNetBoundaryAwareLoss'
    assert type(model.rpn_head).__name__ == 'CBNetCascadeRPNHead'
    # it trains: one loss step on a 64x64 image with one object
    from mmdet.structures import DetDataSample
    from mmdet.structures.mask import BitmapMasks
    from mmengine.structures import InstanceData
    sample = DetDataSample(metainfo=dict(img_shape=(64, 64),
                                         ori_shape=(64, 64),
                                         pad_shape=(64, 64),
                                         batch_input_shape=(64, 64),
                                         scale_factor=(1., 1.)))
    mask = torch.zeros(1, 64, 64, dtype=torch.uint8)
    mask[0, 16:48, 12:40] = 1
    sample.gt_instances = InstanceData(
        bboxes=torch.tensor([[12., 16., 40., 48.]]),
        labels=torch.tensor([0]),
        masks=BitmapMasks(mask.numpy(), 64, 64))
    losses = model.loss(torch.rand(1, 3, 64, 64), [sample])
    total = sum(v.sum() for k, v in losses.items() if 'loss' in k
                and torch.is_tensor(v)) + sum(
                    sum(x.sum() for x in v) for k, v in losses.items()
                    if 'loss' in k and isinstance(v, list))
    assert torch.isfinite(total)
    assert losses['loss_mask'] > 0


#: Where install times are stated.
INSTALL_TIME_FILES = ('README.md', 'docs/install.md', 'docs/faq.md',
                      'tools/install.sh')
#: A time in minutes (``11 min``, ``15.5 minutes``, ``11-17 min``).
MINUTES = re.compile(r'(\d+(?:\.\d+)?)(?:-(\d+))? min(?:utes)?\b')


def _minutes_of(text):
    """The figures of ``text`` in minutes, as written: ``N min`` and
    ``N s`` (to the nearest half minute), as strings (``'13.5'``,
    ``'17'``)."""
    # `6 min 57 s` is one figure, 6 minutes (not 57 s more)
    text = re.sub(r'(\d+) min \d+ s\b', r'\1 min', text)
    found = {m for pair in MINUTES.findall(text) for m in pair if m}
    for seconds in re.findall(r'\b(\d+) s\b', text):
        half = round(int(seconds) / 30) / 2
        found.add(f'{half:g}')
    return found


def measured_install_minutes():
    """(every figure, the mmcv compile's) of docs/install.md's "First-
    install time" section, the one place the install times are recorded
    with their dates and clocks (no JSON record holds them)."""
    text = read_text(osp.join(ROOT, 'docs', 'install.md'))
    section = text.split('## First-install time', 1)[1].split('\n## ')[0]
    rows = [line for line in section.splitlines()
            if line.startswith('| mmcv')]
    assert len(rows) == 1, 'docs/install.md: no single mmcv row in the ' \
        '"First-install time" table'
    return _minutes_of(section), _minutes_of(rows[0])


def test_one_set_of_mmcv_compile_times():
    """Every sentence on compiling mmcv states one of the mmcv compile
    times docs/install.md records, and no minute figure that docs/install.md
    does not record (once 10, 15.5 and 30 in different files). The figures
    are read from docs/install.md, none is written here."""
    recorded, mmcv = measured_install_minutes()
    assert mmcv, 'docs/install.md: the mmcv row states no time'
    stated = {}
    for name in INSTALL_TIME_FILES:
        text = ' '.join(read_text(osp.join(ROOT, name)).replace('#', ' ')
                        .split())
        for sentence in re.split(r'(?<=[.!?])\s', text):
            if 'mmcv' in sentence and re.search(r'compil|build',
                                                sentence):
                for minutes in MINUTES.findall(sentence):
                    stated.setdefault(name, set()).update(
                        m for m in minutes if m)
    assert set(stated) >= set(INSTALL_TIME_FILES), stated
    for name, minutes in stated.items():
        assert minutes <= recorded, (
            f'{name} states install times docs/install.md does not '
            f'record: {sorted(minutes - recorded)}')
        assert minutes & mmcv, (
            f'{name} states no mmcv compile time docs/install.md records '
            f'({sorted(mmcv)}): {sorted(minutes)}')


def test_install_time_check_reads_the_table(tmp_path, monkeypatch):
    """The figures come from docs/install.md: its mmcv row (minutes and
    seconds) and the rest of the section."""
    doc = tmp_path / 'docs' / 'install.md'
    doc.parent.mkdir()
    doc.write_text('# x\n\n## First-install time\n\n| what | a |\n|---|---|\n'
                   '| mmcv built | 11 min (871 s) |\n'
                   '| all | 12 min, then 6 min 57 s |\n\n## Next\n\n'
                   '| 99 min |\n')
    monkeypatch.setattr(sys.modules[__name__], 'ROOT', str(tmp_path))
    recorded, mmcv = measured_install_minutes()
    assert mmcv == {'11', '14.5'}
    assert recorded == {'11', '14.5', '12', '6'}


def test_generated_tables_are_what_their_records_print():
    """Every ``<!-- table: compare_recipes.py ... -->`` region of the docs
    is what its command prints from its committed record now
    (tools/misc/update_doc_tables.py regenerates them)."""
    from cbnet_lab.doc_tables import update_docs
    stale = update_docs(ROOT, check=True, log=lambda *a: None)
    assert not stale, (
        'regenerate with python tools/misc/update_doc_tables.py: ' +
        ', '.join(f'{r.doc}:{r.line}' for r in stale))
