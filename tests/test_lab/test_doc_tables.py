"""Generated results tables (cbnet_lab/doc_tables.py): a marked region
gets what its command prints from its record, nothing else in the page
changes, a stale region is named, malformed marks are errors naming the
page and line; and a real record through the real command."""
import json
import os.path as osp

import pytest
from tool_helpers import load_tool

from cbnet_lab import doc_tables as dt

CMD = ('compare_recipes.py --set realfog_coco --report-only --restore '
       'docs/robustness/x.json')
PAGE = f"""# Page

Text before.

<!-- table: {CMD} -->
| old | table |
<!-- /table -->

Text between.

<!-- table: {CMD} --only "YOLOX-Nano COCO, zero-shot" -->
<!-- /table -->
After.
"""


def fake_render(argv, root, tool='compare_recipes.py'):
    assert tool == 'compare_recipes.py'
    return f'| printed | {len(argv)} args |\n'


def write(tmp_path, text, name='page.md'):
    (tmp_path / name).write_text(text)
    return name


def test_regions_are_found_with_their_commands():
    regions = dt.find_regions(PAGE, 'page.md')
    assert [r.line for r in regions] == [5, 11]
    assert regions[0].argv == ['--set', 'realfog_coco', '--report-only',
                               '--restore', 'docs/robustness/x.json']
    assert regions[1].argv[-2:] == ['--only', 'YOLOX-Nano COCO, zero-shot']
    assert regions[0].body == '| old | table |\n' and regions[1].body == ''


def test_update_rewrites_the_regions_only_and_is_idempotent(tmp_path):
    doc = write(tmp_path, PAGE)
    stale = dt.update_docs(str(tmp_path), [doc], renderer=fake_render,
                           log=lambda *a: None)
    assert [r.line for r in stale] == [5, 11]
    text = (tmp_path / doc).read_text()
    assert text == PAGE.replace('| old | table |\n',
                                '| printed | 5 args |\n').replace(
        '-->\n<!-- /table -->', '-->\n| printed | 7 args |\n<!-- /table -->')
    again = dt.update_docs(str(tmp_path), [doc], renderer=fake_render,
                           log=lambda *a: None)
    assert again == [] and (tmp_path / doc).read_text() == text


def test_check_names_stale_regions_and_writes_nothing(tmp_path):
    doc = write(tmp_path, PAGE)
    stale = dt.update_docs(str(tmp_path), [doc], check=True,
                           renderer=fake_render, log=lambda *a: None)
    assert [(r.doc, r.line) for r in stale] == [(doc, 5), (doc, 11)]
    assert (tmp_path / doc).read_text() == PAGE


@pytest.mark.parametrize('text,match', [
    (f'<!-- table: {CMD} -->\n| a |\n', r'page.md: the last table mark is '
     'not closed'),
    ('x\n<!-- /table -->\n', r'page.md:2: a closing mark without'),
    (f'<!-- table: {CMD} -->\n<!-- table: {CMD} -->\n<!-- /table -->\n',
     r'page.md:2: an opening mark inside a region'),
    ('<!-- table: compare_recipes.py --set x\n --report-only -->\n'
     '<!-- /table -->\n', r'page.md:1: a table mark is one line'),
    ('<!-- table: train.py c.py --report-only -->\n<!-- /table -->\n',
     r"page.md:1: a table region names \['train.py'\]"),
    ('<!-- table: compare_recipes.py --set x -->\n<!-- /table -->\n',
     'page.md:1: the command needs --report-only'),
    (f'<!-- table: {CMD} --work-dir w -->\n<!-- /table -->\n',
     'leave --work-dir out'),
    ('<!-- table: offload_seeds.py a.json --out-dir o -->\n'
     '<!-- /table -->\n', 'leave --out-dir out'),
])
def test_malformed_marks_are_errors_naming_page_and_line(text, match):
    with pytest.raises(ValueError, match=match):
        dt.find_regions(text, 'page.md')


def test_a_failing_command_is_an_error_with_its_output(tmp_path):
    with pytest.raises(RuntimeError, match="invalid choice: 'no_such_set'"):
        dt.render(['--set', 'no_such_set', '--report-only'],
                  dt_root())


def dt_root():
    return osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))


def test_a_real_record_through_the_real_command(tmp_path):
    """Two finished runs in a record: the region gets the harness's own
    table of them (mean and seeds as compare_recipes.py prints them)."""
    runs = []
    for seed, ap in ((0, 0.2), (1, 0.3)):
        runs.append(dict(
            recipe='YOLOX-Nano COCO, zero-shot',
            config='yolox_coco/yolox_nano_coco-zero-shot_dawn-fog.py',
            seed=seed, budget=dict(iters=450, batch_size=4, lr=None,
                                   warmup_iters=50, num_workers=1,
                                   img_scale=[640, 480]),
            train_time_s=None, test_only=True, weights='w.pth',
            metrics={'real fog': {
                'coco/bbox_mAP': ap, 'coco/bbox_mAP_50': 0.4,
                'coco/bbox_mAP_s': 0.1, 'coco/bbox_mAP_m': 0.2,
                'coco/bbox_mAP_l': 0.4}}))
    record = tmp_path / 'record.json'
    record.write_text(json.dumps(dict(set='realfog_coco', runs=runs)))
    argv = ['--set', 'realfog_coco', '--report-only', '--restore',
            str(record), '--seeds', '0', '1', '--only',
            'YOLOX-Nano COCO, zero-shot']
    table = dt.render(argv, dt_root())
    assert '| YOLOX-Nano COCO, zero-shot | 25.0 +- 7.1 | 40.0 +- 0.0 |' \
        in table, table
    # the command-line tool: --check fails on the stale page, then passes
    page = tmp_path / 'page.md'
    page.write_text(f'<!-- table: compare_recipes.py '
                    f'{" ".join(repr(a) for a in argv)} -->\n'
                    '<!-- /table -->\n')
    tool = load_tool('misc/update_doc_tables.py')
    tool.ROOT = str(tmp_path)
    assert tool.main(['page.md', '--check']) == 1
    assert page.read_text().count('\n') == 2
    with pytest.raises(SystemExit):
        tool.main(['missing.md'])


def test_an_offload_table_through_the_real_command():
    """The committed records of three edge seeds: the region gets
    offload_seeds.py's table, its 'always server' row the mean +- std of
    the records' own values (computed here)."""
    import statistics
    folder = osp.join('docs', 'serving', 'realfog', 'offload_coco')
    records = [osp.join(folder, f'seed{s}.json') for s in (0, 1, 2)]
    region = dt.find_regions(
        f'<!-- table: offload_seeds.py {" ".join(records)} -->\n'
        '<!-- /table -->\n', 'page.md')[0]
    assert region.tool == 'offload_seeds.py'
    table = dt.render(region.argv, dt_root(), tool=region.tool)
    aps = []
    for path in records:
        with open(osp.join(dt_root(), path)) as f:
            rows = json.load(f)['rows']
        aps += [r['bbox_mAP'] for r in rows if r['policy'] == 'always server']
    assert len(aps) == 3
    row = [line for line in table.splitlines()
           if line.startswith('| always server |')]
    assert row and (f'| {statistics.mean(aps):.1f} +- '
                    f'{statistics.stdev(aps):.1f} |') in row[0], row


def test_a_record_table_through_the_real_command():
    """A speed record the harness does not tabulate: the region gets
    record_table.py's table, its ratio the medians' ratio of the record
    (computed here)."""
    import statistics
    record = osp.join('docs', 'benchmarks', 'device_like_for_like.json')
    region = dt.find_regions(
        f'<!-- table: record_table.py like-for-like {record} --table '
        'ratios -->\n<!-- /table -->\n', 'page.md')[0]
    assert region.tool == 'record_table.py'
    table = dt.render(region.argv, dt_root(), tool=region.tool)
    with open(osp.join(dt_root(), record)) as f:
        cell = json.load(f)['inference_round_times_s']['s512_t1']
    ratio = statistics.median(cell['b2']) / statistics.median(
        cell['swin-s_k300'])
    assert f'| 512x1024, 1 thread | {ratio:.2f} / ' in table, table


def test_one_process_renders_every_region_and_names_a_failing_one(tmp_path):
    """update_docs renders each distinct command once, all in one process;
    a command that fails is an error naming its page and line."""
    good = ('<!-- table: record_table.py kernels '
            'docs/benchmarks/kernels_cuda_h100.json -->\n<!-- /table -->\n')
    (tmp_path / 'a.md').write_text(good + '\n' + good)
    (tmp_path / 'b.md').write_text(good)
    calls = []

    def counting(argv, root, tool='compare_recipes.py'):
        calls.append((tool, tuple(argv)))
        return '| t |\n'

    stale = dt.update_docs(str(tmp_path), ['a.md', 'b.md'], check=True,
                           renderer=counting, log=lambda *a: None)
    assert len(calls) == 1 and len(stale) == 3
    tables = dt.render_many(
        [('record_table.py', ['kernels',
                              'docs/benchmarks/kernels_cuda_h100.json']),
         ('record_table.py', ['scaling', 'docs/benchmarks/no_such.json'])],
        dt_root())
    assert tables[0].startswith('| kernel |')
    assert isinstance(tables[1], RuntimeError) and 'no_such.json' in \
        str(tables[1])
    (tmp_path / 'c.md').write_text(
        'x\n<!-- table: record_table.py scaling no_such.json -->\n'
        '<!-- /table -->\n')
    with pytest.raises(RuntimeError, match=r'c\.md:2: record_table\.py'):
        dt.update_docs(str(tmp_path), ['c.md'], check=True,
                       log=lambda *a: None)
