"""Tables printed from speed, kernel, backbone, proposal and model-index
records (cbnet_lab/record_tables.py, tools/misc/record_table.py): each
kind on a small record whose figures are worked out here, the committed
records through the command line, and bad keys named."""
import json
import os.path as osp
import statistics

import pytest
from tool_helpers import load_tool

from cbnet_lab import record_tables as rt

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
BENCH = osp.join(ROOT, 'docs', 'benchmarks')


def rows(table):
    """The body rows of a Markdown table as lists of cells."""
    lines = [line for line in table.splitlines() if line.startswith('|')]
    return [[c.strip() for c in line.strip('|').split(' | ')]
            for line in lines[2:]]


def like_for_like_record():
    """One 512 cell holding every model (3 rounds) and the two 1024 cells
    of B2 and B5 at 300 proposals, each with its own Swin-S."""
    return dict(inference_round_times_s={
        's512_t1': {'b2': [2.0, 4.0, 3.0], 'b5': [6.0, 6.0, 6.0],
                    'swin-s_k300': [4.0, 4.0, 4.0], 'b2_k1000': [5, 5, 5],
                    'b5_k1000': [10, 10, 10], 'swin-s': [8, 8, 8]},
        's1024_t2_b2_k300': {'b2': [9.0, 9.0], 'swin-s_k300': [3.0, 3.0]},
        's1024_t2_b5_k300': {'b5': [20.0, 20.0], 'swin-s_k300': [5.0, 5.0]},
        's1024_t2_b2_k1000': {'b2_k1000': [8, 8], 'swin-s': [4, 4]},
        's1024_t2_b5_k1000': {'b5_k1000': [12, 12], 'swin-s': [4, 4]},
        'gpu_1024x2048': {'b2': [0.2], 'b5': [0.3], 'swin-s_k300': [0.1],
                          'b2_k1000': [0.2], 'b5_k1000': [0.4],
                          'swin-s': [0.2]},
    })


def test_like_for_like_ratios_are_medians_over_the_same_process():
    table = rt.like_for_like(like_for_like_record(), 'ratios')
    assert rows(table) == [
        ['512x1024, 1 thread', '0.75 / 0.62', '1.50 / 1.25'],
        ['1024x2048, 2 threads', '3.00 / 2.00', '4.00 / 3.00'],
    ]
    latency = rows(rt.like_for_like(like_for_like_record(), 'latency'))
    # one Swin-S where both ran in one process, two where each had its own
    assert latency[0][:5] == ['512x1024, 1 thread', '300', '3.00', '6.00',
                              '4.00']
    assert latency[2][4] == '3.00 / 5.00'
    gpu = rows(rt.like_for_like(like_for_like_record(), 'gpu'))
    assert gpu == [['1024x2048', '300', '200', '300', '100', '2.00', '3.00'],
                   ['1024x2048', '1000', '200', '400', '200', '1.00',
                    '2.00']]
    with pytest.raises(ValueError, match='no table'):
        rt.like_for_like(like_for_like_record(), 'nope')


def test_like_for_like_training_and_gflops():
    def run(model, step, mib):
        return dict(results={model: dict(step_s=[step], peak_mib=mib)})

    training = {}
    for m, (t1, t2, mem) in {'cbnet_mit-b5': (40.0, 20.0, 4096.0),
                             'cascade-mask-rcnn_swin-s': (20.0, 10.0,
                                                          2048.0)}.items():
        training[f'train_t1_{m}'] = run(m, t1, mem)
        training[f'train_t2_{m}'] = run(m, t2, mem)
    training['train_gpu'] = dict(results={
        'cbnet_mit-b5': dict(step_s=[0.6], peak_mib=3072.0),
        'cascade-mask-rcnn_swin-s': dict(step_s=[0.3], peak_mib=1024.0)})
    record = dict(inference_round_times_s={}, training=training, gflops=dict(
        values={'cbnet_mit-b5 512x1024': dict(predict=30.0, features=20.0),
                'cascade-mask-rcnn_swin-s 512x1024': dict(predict=15.0,
                                                          features=5.0)}))
    assert rows(rt.like_for_like(record, 'training')) == [
        ['CBNet MiT-B5', '40.0', '2.00', '20.0', '2.00', '4.0', '2.00',
         '0.60', '2.00', '3.0'],
        ['Cascade Mask R-CNN Swin-S', '20.0', '1.00', '10.0', '1.00', '2.0',
         '1.00', '0.30', '1.00', '1.0']]
    assert rows(rt.like_for_like(record, 'gflops')) == [
        ['CBNet MiT-B5', '20.0 / 30.0', '4.00 / 2.00'],
        ['Cascade Mask R-CNN Swin-S', '5.0 / 15.0', '1.00 / 1.00']]


def test_scaling_grows_from_the_smallest_input():
    def cells(*seconds):
        return [dict(size=[h, 2 * h], seconds=s, peak_mib=100.0 * s)
                for h, s in zip((256, 512), seconds)]

    record = dict(scaling=dict(sizes={'cbnet_mit-b5': cells(2.0, 8.0),
                                      'swin-s_k300': cells(4.0, 4.0)}))
    table = rt.scaling(record)
    assert rows(table)[0] == ['CBNet MiT-B5', '2.00 / 200', '8.00 / 800',
                              '4.0x', '0.50, 2.00']
    assert 'growth 256x512 -> 512x1024' in table


def test_kernels_pair_each_implementation_with_the_stock_op():
    record = dict(rows=[
        dict(kernel='k', setting='s', impl='ours', median_ms=3.0,
             iqr_ms=0.5, vs_stock=1.5),
        dict(kernel='k', setting='s', impl='stock', median_ms=2.0,
             iqr_ms=0.1, vs_stock=1.0)])
    assert rows(rt.kernels(record)) == [
        ['k', 's', 'ours', '3.00 (0.50)', 'stock', '2.00 (0.10)', '1.50']]
    threads = {'1': record, '2': dict(rows=[
        dict(r, median_ms=r['median_ms'] / 2) for r in record['rows']])}
    assert rows(rt.kernel_threads(threads))[0] == [
        'k', 's', 'ours', '3.00', '1.50', '2.0x']


def test_backbone_tables_pivot_the_encodings():
    def result(pos, t, mib):
        return dict(arch='b0', pos=pos, time_s=t, peak_mib=mib)

    record = dict(size=[512, 1024], runs=3, results=[
        result('ope', 1.0, 100.0), result('cspe', 2.0, 200.0),
        result('cspe, chunk 8192', 1.0, 50.0)])
    assert rows(rt.backbone(record)) == [
        ['MiT-B0, 512x1024 (median of 3)', '1.00 / 100', '2.00 / 200',
         '1.00 / 50', '0.50, 0.25']]
    threads = {'1': record, '2': dict(record, results=[
        dict(r, time_s=r['time_s'] / 4) for r in record['results']])}
    assert rows(rt.backbone_threads(threads))[1] == [
        'MiT-B0 `cspe`', '2.000', '0.500', '4.0x']


def test_proposals_and_model_index():
    record = dict(results={'m': dict(
        proposals_per_image=300.0, recall={'0.5': 0.8, '0.9': 0.25},
        mean_best_iou=0.7, positive_share={'0.5': 0.3333})})
    assert rows(rt.proposals(record)) == [
        ['m', '300', '0.800', '0.250', '0.700', '0.333']]
    metafile = dict(Models=[
        dict(Config='configs/a.py', Metadata=dict(Epochs=12), Results=[
            dict(Dataset='X (paper, Table 1)', Metrics={'AP': 41.4}),
            dict(Dataset='X (paper, Table 1)', Metrics={'mIoU': 35.9}),
            dict(Dataset='Y (paper, Table 2)', Metrics={'AP': 39.1})]),
        dict(Config='configs/b.py', Results=[])])
    assert rows(rt.model_index([metafile])) == [
        ['`configs/a.py`', '12', 'X (paper, Table 1)', '41.4', '35.9'],
        ['`configs/a.py`', '12', 'Y (paper, Table 2)', '39.1', '-'],
        ['`configs/b.py`', '-', '-', '-', '-']]
    assert rows(rt.model_index([metafile], datasets=['Table 2'])) == [
        ['`configs/a.py`', '12', 'Y (paper, Table 2)', '39.1']]


def test_a_missing_key_names_what_the_record_holds():
    with pytest.raises(KeyError, match=r"'gpu\.9' \(at '9': \['1024'\]"):
        rt.part({'gpu': {'1024': {}}}, 'gpu.9')


def test_the_command_line_on_the_committed_records(tmp_path):
    """The like-for-like ratios of the committed record are the medians'
    ratios, computed here; every kind prints from its record; the table is
    written to --out-dir."""
    tool = load_tool('misc/record_table.py')
    path = osp.join(BENCH, 'device_like_for_like.json')
    md = tool.main(['like-for-like', path, '--table', 'ratios', '--out-dir',
                    str(tmp_path)])
    assert (tmp_path / 'record_table.md').read_text() == md
    with open(path) as f:
        cell = json.load(f)['inference_round_times_s']['s512_t2']
    ratio = statistics.median(cell['b5']) / statistics.median(
        cell['swin-s_k300'])
    assert rows(md)[1][0] == '512x1024, 2 threads'
    assert rows(md)[1][2].startswith(f'{ratio:.2f} / ')
    for argv in (['scaling', 'scaling_like_for_like.json'],
                 ['kernels', 'kernels_cuda_h100.json'],
                 ['backbone', 'device_h200_chunk_threads.json', '--key',
                  'gpu'],
                 ['kernel-threads', 'device_h200_chunk_threads.json',
                  '--key', 'cpu_threads.kernels_256x512_c128']):
        argv[1] = osp.join(BENCH, argv[1])
        assert len(rows(tool.main(argv))) >= 3, argv
    index = tool.main(['model-index',
                       osp.join(ROOT, 'configs', 'cbnet', 'metafile.yml')])
    assert '| `configs/cbnet_cityscapes.py` | 12 |' in index
    with pytest.raises(SystemExit):
        tool.main(['scaling', path, path])


def test_proposals_over_seeds_are_means_and_sample_stds_in_percent():
    def run(r5):
        return dict(proposals_per_image=300.0, recall={'0.5': r5},
                    mean_best_iou=0.5, positive_share={'0.5': 0.25})

    record = dict(results={'a s0': run(0.7), 'a s1': run(0.8),
                           'a s2': run(0.9), 'b': run(0.5)})
    assert rows(rt.proposals_seeds(record)) == [
        ['a', '3', '80.0 +- 10.0', '50.0 +- 0.0', '25.0 +- 0.0'],
        ['b', '1', '50.0 +- 0.0', '50.0 +- 0.0', '25.0 +- 0.0']]


def test_benchmark_prints_its_tables_without_the_runs_notes():
    with open(osp.join(ROOT, 'docs', 'serving', 'edge_benchmark',
                       'benchmark.json')) as f:
        record = json.load(f)
    table = rt.benchmark(record)
    assert all(line.startswith('|') for line in table.splitlines())
    assert 'UTC' not in table and record['meta']['command'] not in table
    edge = rows(table)[0]
    assert edge[0] == 'edge_fcos-lite_320' and edge[6] == '1.00'


def test_edge_speed_is_over_the_reference():
    def model(p50, fps):
        return dict(p50=p50, p95=2 * p50, cpu_p50=p50, fps=fps,
                    input=[192, 320])

    record = dict(meta=dict(models={'a': dict(runtime='ONNX Runtime'),
                                    'b': dict(runtime='PyTorch eager')},
                            command='edge_speed.py --reference b'),
                  results={'a': model(0.01, 100.0), 'b': model(0.04, 25.0)})
    assert rows(rt.serving_tables.edge_speed(record)) == [
        ['a', 'ONNX Runtime', '192x320', '0.0100 / 0.0200', '100.0',
         '0.0100', '0.25'],
        ['b', 'PyTorch eager', '192x320', '0.0400 / 0.0800', '25.0',
         '0.0400', '1.00']]
    assert rows(rt.serving_tables.edge_speed(record, 'a'))[1][-1] == '4.00'
    with pytest.raises(KeyError, match="no model 'c'"):
        rt.serving_tables.edge_speed(record, 'c')


def test_load_test_fallback_and_offload_tables():
    def level(c, p50, rate, errors=0):
        return dict(concurrency=c, p50_s=p50, p99_s=2 * p50,
                    throughput_img_s=rate, errors=errors)

    one = dict(levels=[level(1, 0.5, 2.0), level(2, 1.0, 2.0, errors=1)])
    two = dict(levels=[level(1, 0.5, 2.0), level(2, 0.5, 4.0)])
    assert rows(rt.serving_tables.load_test([one, two], ['r1', 'r2'])) == [
        ['r1', '0.500 / 2.00', '1.000 / 2.000, 2.00', '1'],
        ['r2', '0.500 / 2.00', '0.500 / 1.000, 4.00', '0']]
    with pytest.raises(ValueError, match='concurrency levels'):
        rt.serving_tables.load_test([one, dict(levels=[level(1, 1, 1)])])

    def secs(median):
        return dict(median=median, mean=median, p95=2 * median)

    fallback = dict(
        _setup=dict(date='x'),
        up=dict(what='up', where=dict(server=3, local=1),
                seconds=dict(server=secs(0.5), local=secs(0.1))),
        down=dict(what='down', where={'local-fallback': 3, 'local': 1},
                  fallback_errors=dict(ConnectionError=3),
                  seconds={'local-fallback': secs(0.2),
                           'local': secs(0.1)}))
    assert rows(rt.serving_tables.fallback(fallback)) == [
        ['up', '3 / 0 / 1', '-', '0.500 / 1.000', '0.100 / 0.200'],
        ['down', '0 / 3 / 1', '3 ConnectionError', '0.200 / 0.400',
         '0.100 / 0.200']]

    def row(policy, rate, ap, **extra):
        return dict(policy=policy, offload_rate=rate, seconds=0.25,
                    offloaded={'clear': rate, '0.02': rate}, bbox_mAP=ap,
                    bbox_mAP_50=2 * ap, **extra)

    side = dict(local=dict(bbox_mAP=10.0), server=dict(bbox_mAP=20.0))
    offload = dict(conditions=['clear', '0.02'],
                   transmission={'clear': 0.8, '0.02': 0.5},
                   by_condition={'clear': side, '0.02': side},
                   rows=[row('always local', 0.0, 10.0),
                         row('random 1/2', 0.5, 15.0,
                             std=dict(bbox_mAP=0.25))])
    table = rt.serving_tables.offload(offload)
    assert rows(table)[:2] == [
        ['always local', '0%', '0%', '0%', '10.0', '20.0', '0.250'],
        ['random 1/2', '50%', '50%', '50%', '15.0 +- 0.2', '30.0', '0.250']]
    assert '| beta 0.02 | 0.500 | 10.0 | 20.0 |' in table


def comparison(*runs):
    """A comparison record of ``(recipe, seed, {condition: {key: v}})``."""
    return dict(runs=[dict(recipe=r, seed=s, metrics=m) for r, s, m in runs])


def test_results_summary_quotes_seed_means_of_the_records():
    box, box50 = 'coco/bbox_mAP', 'coco/bbox_mAP_50'
    records = {
        'a.json': comparison(
            ('stock', 0, {'fog': {box: 0.10, box50: 0.20}}),
            ('stock', 1, {'fog': {box: 0.12, box50: 0.22}}),
            ('zero', 0, {'fog': {box: 0.30, box50: -1}}),
            ('zero', 1, {'fog': {box: 0.30, box50: -1}})),
        'lfl.json': dict(inference_round_times_s={'s512_t2': {
            'b5': [3.0, 3.0], 'swin-s_k300': [2.0, 2.0]}}),
    }
    spec = dict(columns=['stock', 'ours'], rows=[
        dict(set='fog', metrics=['box AP', 'box AP50'], metric='AP / AP50',
             record='a.json', condition='fog', doc=['page', 'p.md#fog'],
             cells=[[dict(recipe='stock', bold=True, text='{} (x)')],
                    [dict(recipe='zero', metrics=['box AP'], spread=False),
                     dict(text='not run')]]),
        dict(set='speed', metric='ratio', cells=[
            [dict(record='lfl.json', like_for_like=dict(
                model='swin-s', threads=2, proposals=300, sizes=[512]))],
            [dict(record='lfl.json', like_for_like=dict(
                model='b5', threads=2, proposals=300, sizes=[512]))]]),
    ])
    table = rt.results_summary(spec, load=records.__getitem__)
    assert rows(table) == [
        ['fog', 'AP / AP50', '**11.0 +- 1.4 / 21.0 +- 1.4** (x)',
         '30.0; not run', '[page](p.md#fog), [record](a.json)'],
        ['speed', 'ratio', '1.00', '1.50', '[record](lfl.json)']]
    assert table.startswith('| set | metric | stock | ours | source |')


@pytest.mark.parametrize('quote,error', [
    (dict(recipe='nope'), "no run of 'nope'"),
    (dict(recipe='stock', condition='clear'), "reports no box AP on 'clear'"),
    (dict(recipe='stock', spread=False), 'spread: false for values that '
     'differ'),
    (dict(recipe='stock', colour='red'), "unknown keys \\['colour'\\]"),
])
def test_results_summary_names_what_it_cannot_quote(quote, error):
    record = comparison(('stock', 0, {'fog': {'coco/bbox_mAP': 0.1}}),
                        ('stock', 1, {'fog': {'coco/bbox_mAP': 0.2}}))
    spec = dict(columns=['x'], rows=[dict(
        set='s', metrics=['box AP'], record='r', condition='fog',
        cells=[[quote]])])
    with pytest.raises((KeyError, ValueError), match=error):
        rt.results_summary(spec, load=lambda path: record)
    spec['columns'] = ['x', 'y']
    with pytest.raises(ValueError, match='1 cells under 2 columns'):
        rt.results_summary(spec, load=lambda path: record)


def test_the_command_line_on_the_committed_serving_records_and_summary(
        monkeypatch):
    """The new kinds through the command line on the committed records:
    several records with their names, and the README's summary from its
    spec (its records read from the repository root)."""
    tool = load_tool('misc/record_table.py')
    serving = osp.join(ROOT, 'docs', 'serving', 'realfog')
    load = [osp.join(serving, 'load', f'pass2_r{r}_b1.json') for r in (1, 2)]
    md = tool.main(['load-test'] + load + ['--names', 'one', 'two'])
    assert [r[0] for r in rows(md)] == ['one', 'two']
    with pytest.raises(SystemExit):
        tool.main(['load-test'] + load + ['--names', 'one'])
    speed = osp.join(serving, 'edge_speed_yolox', 'edge_speed.json')
    assert rows(tool.main(['edge-speed', speed]))[-1][-1] == '1.00'
    assert len(rows(tool.main(['fallback', osp.join(
        serving, 'load', 'fallback.json')]))) == 3
    monkeypatch.chdir(ROOT)
    summary = tool.main(['results-summary', 'docs/results_summary.yml'])
    assert len(rows(summary)) >= 8
    assert all('[record](docs/' in r[-1] for r in rows(summary))


def test_offload_seeds_in_short():
    def stat(mean, std):
        return dict(mean=mean, std=std)

    record = dict(conditions=['clear', 'fog'], rows=[
        dict(row='always local', offload_rate=stat(0.0, 0.0),
             bbox_mAP=stat(15.0, 2.0),
             condition_ap=dict(clear=stat(10.0, 1.0), fog=stat(20.0, 3.0))),
        dict(row='haze, decile 0.5', offload_rate=stat(0.5, 0.01),
             bbox_mAP=stat(19.0, 1.5), gain_over_random=stat(-3.9, 1.0),
             condition_ap=dict(clear=stat(11.0, 2.0), fog=stat(27.0, 2.0)))])
    assert rows(rt.serving_tables.offload_seeds(record)) == [
        ['always local', '0 +- 0 %', '15.0 +- 2.0', '10.0 +- 1.0',
         '20.0 +- 3.0', '-'],
        ['haze, decile 0.5', '50 +- 1 %', '19.0 +- 1.5', '11.0 +- 2.0',
         '27.0 +- 2.0', '-3.9 +- 1.0']]
