"""The comparison harness (cbnet_lab/recipe_comparison.py)."""
import glob
import json
import os.path as osp
from dataclasses import asdict

import numpy as np
import pytest
from harness_helpers import fake_run, fake_training, stub_comparison
from tool_helpers import load_tool

from cbnet_lab import config_edits as ce
from cbnet_lab import executors
from cbnet_lab import recipe_comparison as rc
from cbnet_lab import report
from cbnet_lab.sets import Recipe

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))


def test_every_builtin_recipe_config_exists():
    for name, recipes in rc.RECIPE_SETS.items():
        resolved = rc.resolve_recipes(name)
        assert [n for n, _ in resolved] == [n for n, _ in recipes]
        assert all(osp.isfile(p) for _, p in resolved)


def test_resolve_recipes_errors(tmp_path):
    with pytest.raises(ValueError, match='unknown recipe set'):
        rc.resolve_recipes('nope')
    with pytest.raises(ValueError, match='no recipes'):
        rc.resolve_recipes()
    with pytest.raises(FileNotFoundError, match='missing.py'):
        rc.resolve_recipes(configs=['x=missing.py'])
    cfg = tmp_path / 'a.py'
    cfg.write_text('x = 1\n')
    assert rc.resolve_recipes(configs=[str(cfg)])[0][0] == 'a'
    with pytest.raises(ValueError, match='unique'):
        rc.resolve_recipes(configs=[f'a={cfg}', f'a={cfg}'])


def test_weights_sources_of_test_time_variants():
    """A set row's ``weights_of``, or ``--weights-of`` for a recipe
    without a row, names an earlier recipe that trains; anything else is a
    clear error. No config is read."""
    recipes = [('b', 'base.py'), ('v', 'variant.py')]
    rows = dict(v=Recipe(name='v', config='variant.py', weights_of='b'))
    assert rc.weights_sources(recipes, rows) == dict(b=None, v='b')
    assert rc.weights_sources(recipes, weights_of=dict(v='b')) == \
        dict(b=None, v='b')
    assert rc.weights_sources(recipes) == dict(b=None, v=None)
    with pytest.raises(ValueError, match='before'):
        rc.weights_sources(recipes[::-1], weights_of=dict(v='b'))
    with pytest.raises(ValueError, match='before'):
        rc.weights_sources(recipes[1:], rows)
    # a variant of a variant: its weights were never trained
    with pytest.raises(ValueError, match='before'):
        rc.weights_sources(recipes + [('c', 'chained.py')],
                           weights_of=dict(v='b', c='v'))
    with pytest.raises(ValueError, match=r"no recipe named \['x'\]"):
        rc.weights_sources(recipes, weights_of=dict(x='b'))


def test_weights_of_option(capsys):
    tool = load_tool('analysis_tools/compare_recipes.py')
    args = tool.parse_args(['--configs', 'a.py', 'b.py', '--weights-of',
                            'b=a'])
    assert args.weights_of == dict(b='a')
    assert tool.parse_args(['--set', 'speed']).weights_of == {}
    with pytest.raises(SystemExit):
        tool.parse_args(['--configs', 'a.py', '--weights-of', 'b'])
    assert '--weights-of NAME=SOURCE' in capsys.readouterr().err


def test_a_variant_without_its_source_weights_is_a_clear_error(tmp_path):
    config = osp.join(ROOT, 'configs', 'demo', 'rpn',
                      'crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
    with pytest.raises(FileNotFoundError, match="weights of 'CRPN', seed 3"):
        rc.run_recipe('k100', config, 3, ce.Budget(iters=5), str(tmp_path),
                      [0.02], str(tmp_path), weights_of='CRPN')


def test_summarize_mean_std_and_drop_against_numpy():
    runs = [fake_run('A', s, c, f) for s, (c, f) in
            enumerate([(0.30, 0.20), (0.34, 0.21), (0.26, 0.17)])]
    runs.append(fake_run('B', 0, 0.10, -1))  # -1: MMDet's "nothing"
    summary = rc.summarize(runs, [0.02])
    assert summary['columns'] == ['mask AP']
    assert summary['recipes'] == ['A', 'B']
    a = summary['summary']['A']
    clear = np.array([30., 34., 26.])
    foggy = np.array([20., 21., 17.])
    assert a['clear']['mask AP']['mean'] == pytest.approx(clear.mean())
    assert a['clear']['mask AP']['std'] == pytest.approx(clear.std(ddof=1))
    drop = a['foggy beta=0.02']['mask AP drop']
    assert drop['mean'] == pytest.approx((clear - foggy).mean())
    assert drop['std'] == pytest.approx((clear - foggy).std(ddof=1))
    assert a['train time (s)']['mean'] == pytest.approx(11.0)
    b = summary['summary']['B']
    assert b['foggy beta=0.02']['mask AP'] is None
    assert b['foggy beta=0.02']['mask AP drop'] is None
    md = report.to_markdown(summary)
    assert '**clear**' in md and '**foggy beta=0.02**' in md
    assert '| A | 30.0 +- 4.0 | 11.0 +- 1.0 |' in md
    assert '| B | - | - |' in md


def test_a_box_only_recipe_shows_dashes_for_masks_not_zero():
    runs = [fake_run('masks', 0, 0.3, 0.2),
            fake_run('boxes', 0, 0.4, 0.3, key='coco/bbox_mAP')]
    runs[0]['metrics']['clear']['coco/bbox_mAP'] = 0.35
    runs[0]['metrics']['foggy beta=0.02']['coco/bbox_mAP'] = 0.25
    summary = rc.summarize(runs, [0.02])
    assert summary['columns'] == ['box AP', 'mask AP']
    boxes = summary['summary']['boxes']['clear']
    assert boxes['mask AP'] is None
    assert boxes['box AP']['mean'] == pytest.approx(40.0)
    assert '| boxes | 40.0 | - |' in report.to_markdown(summary)


def test_proposal_columns_are_picked_for_rpn_runs():
    runs = [fake_run('R', 0, 0.5, 0.4, key='coco/AR@1000')]
    for run in runs:
        for cond in run['metrics'].values():
            cond.update({'coco/AR@100': 0.2, 'coco/AR@300': 0.3})
    summary = rc.summarize(runs, [0.02])
    assert summary['columns'] == ['AR@100', 'AR@300', 'AR@1000']


@pytest.mark.slow
def test_compare_end_to_end_trained_beats_untrained(
        cityscapes_like_root, tmp_path, capsys):
    """The CLI on the tiny generated data, one seed: the RPN set's CBNet
    CRPN trained 40 iterations against the same model untrained (0). The
    table has its structure; the trained proposals recall more. A
    test-time variant (100 proposals kept) tests the trained weights. A
    rerun reads the finished runs back (resumable)."""
    tool = load_tool('analysis_tools/compare_recipes.py')
    crpn = osp.join(ROOT, 'configs', 'demo', 'rpn',
                    'crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
    common = ['--configs', f'CRPN={crpn}', '--data-root',
              cityscapes_like_root, '--seeds', '0', '--batch-size', '2',
              '--num-workers', '0', '--betas', '0.02', '--warmup-iters',
              '5']
    untrained = tool.main(common + ['--iters', '0', '--work-dir',
                                    str(tmp_path / 'untrained')])
    # a test-time variant: the CRPN's weights, 100 proposals kept
    variant = tmp_path / 'k100.py'
    variant.write_text(f"_base_ = '{crpn}'\n"
                       'model = dict(test_cfg=dict(rpn=dict('
                       'max_per_img=100)))\n')
    with_variant = common + [
        '--iters', '40', '--work-dir', str(tmp_path / 'trained'),
        '--configs', f'CRPN={crpn}', f'k100={variant}', '--weights-of',
        'k100=CRPN'
    ]
    trained = tool.main(with_variant)
    for record, out in ((untrained, 'untrained'), (trained, 'trained')):
        assert osp.isfile(tmp_path / out / 'compare.png')
        with open(tmp_path / out / 'compare.json') as f:
            assert json.load(f)['summary'] == record['summary']
        md = (tmp_path / out / 'compare.md').read_text()
        assert '| CRPN |' in md and '**foggy beta=0.02**' in md
        assert record['summary']['columns'] == ['AR@100', 'AR@300',
                                                'AR@1000']
    ar = [r['summary']['summary']['CRPN']['clear']['AR@1000']['mean']
          for r in (untrained, trained)]
    assert ar[1] > ar[0], ar
    # the variant tested the same weights, trained nothing, and with 100
    # proposals kept recalls as much at 100 and no more at 1000
    runs = {r['recipe']: r for r in trained['runs']}
    assert runs['k100']['weights_of'] == 'CRPN'
    assert runs['k100']['train_time_s'] is None
    assert not osp.exists(tmp_path / 'trained' / 'k100' / 'seed0' /
                          'iter_40.pth')
    clear = {n: r['metrics']['clear'] for n, r in runs.items()}
    assert clear['k100']['coco/AR@100'] == pytest.approx(
        clear['CRPN']['coco/AR@100'], abs=1e-3)
    assert clear['k100']['coco/AR@1000'] < clear['CRPN']['coco/AR@1000']
    assert '| k100 |' in (tmp_path / 'trained' / 'compare.md').read_text()
    again = tool.main(with_variant)
    assert 'already done' in capsys.readouterr().out
    assert again['runs'] == trained['runs']


def test_a_finished_run_of_another_budget_is_not_mixed_in(tmp_path):
    path = tmp_path / 'result.json'
    budget = ce.Budget(iters=300, batch_size=4, img_scale=(512, 256))
    path.write_text(json.dumps(dict(
        recipe='a', seed=0, metrics={},
        budget=json.loads(json.dumps(asdict(budget))))))
    assert rc.read_result(str(path), budget)['recipe'] == 'a'
    with pytest.raises(ValueError, match=r"'iters': \(300, 120\)"):
        rc.read_result(str(path), ce.Budget(iters=120, batch_size=4,
                                            img_scale=(512, 256)))
    with pytest.raises(ValueError, match='img_scale'):
        rc.read_result(str(path), ce.Budget(iters=300, batch_size=4))
    # records written before img_scale existed read as img_scale None
    old = asdict(ce.Budget())
    del old['img_scale']
    path.write_text(json.dumps(dict(recipe='b', seed=0, budget=old)))
    assert rc.read_result(str(path), ce.Budget())['recipe'] == 'b'


def test_a_finished_run_of_other_cfg_options_is_not_mixed_in(tmp_path):
    """A run records the --cfg-options it trained with; a comparison
    giving others (or none) refuses it, as it refuses another budget."""
    path = tmp_path / 'result.json'
    budget = ce.Budget(iters=3)
    opts = {'optim_wrapper.paramwise_cfg.custom_keys.backbone.lr_mult': 1.0}
    path.write_text(json.dumps(dict(
        recipe='a', seed=0, metrics={}, cfg_options=opts,
        budget=json.loads(json.dumps(asdict(budget))))))
    assert rc.read_result(str(path), budget, dict(opts))['recipe'] == 'a'
    with pytest.raises(ValueError, match=r'lr_mult.*\(none\)'):
        rc.read_result(str(path), budget)
    other = {'optim_wrapper.paramwise_cfg.custom_keys.backbone.lr_mult': 0.1}
    with pytest.raises(ValueError, match='cfg-options'):
        rc.read_result(str(path), budget, other)
    # a run without overrides (every record written before they were
    # recorded) reads only where none are given
    path.write_text(json.dumps(dict(
        recipe='b', seed=0, metrics={},
        budget=json.loads(json.dumps(asdict(budget))))))
    assert rc.read_result(str(path), budget)['recipe'] == 'b'
    assert rc.read_result(str(path), budget, {})['recipe'] == 'b'
    with pytest.raises(ValueError, match='cfg-options'):
        rc.read_result(str(path), budget, opts)


def test_restore_runs_of_a_saved_record(tmp_path):
    budget = ce.Budget(iters=3)
    runs = [fake_run('x', 0, 0.2, 0.1), fake_run('x', 1, 0.3, 0.2)]
    record = tmp_path / 'compare.json'
    record.write_text(json.dumps(dict(
        budget=json.loads(json.dumps(asdict(budget))), runs=runs)))
    out = tmp_path / 'out'
    assert rc.restore_runs(str(record), str(out), budget) == 2
    assert rc.read_result(rc.result_file(str(out), 'x', 1),
                          budget)['metrics'] == runs[1]['metrics']
    # already there: kept, not rewritten
    assert rc.restore_runs(str(record), str(out), budget) == 0
    with pytest.raises(ValueError, match='cannot be mixed in'):
        rc.restore_runs(str(record), str(tmp_path / 'o2'),
                        ce.Budget(iters=4))


def test_report_only_tabulates_a_record_and_lists_what_is_left_out(
        tmp_path, monkeypatch):
    """--report-only: the finished runs of a restored record are
    tabulated (against numpy), the rest listed, nothing trained, no data
    read, no machine claimed; nothing finished is a clear error."""
    budget = ce.Budget(iters=3)
    runs = [fake_run('x', 0, 0.2, 0.1), fake_run('x', 1, 0.4, 0.2),
            fake_run('y', 0, 0.3, 0.3)]
    record = tmp_path / 'compare.json'
    record.write_text(json.dumps(dict(
        budget=json.loads(json.dumps(asdict(budget))), runs=runs)))
    out = str(tmp_path / 'out')
    rc.restore_runs(str(record), out, budget)

    def no_training(*args, **kwargs):
        raise AssertionError('--report-only trained a run')

    stub_comparison(monkeypatch, no_training)
    logs = []
    got = rc.compare([('x', 'x.py'), ('y', 'y.py')], [0, 1], budget,
                     str(tmp_path / 'no_data_here'), [0.02], out,
                     log=logs.append, train=False)
    assert got['missing'] == [['y', 1]] and got['machine'] is None
    x = got['summary']['summary']['x']['clear']['mask AP']
    assert x['n'] == 2 and x['mean'] == pytest.approx(30.0)
    assert x['std'] == pytest.approx(np.std([20., 40.], ddof=1))
    assert got['summary']['summary']['y']['clear']['mask AP']['n'] == 1
    assert any('y, seed 1: not finished, left out' in line for line in logs)
    with open(osp.join(out, 'compare.md')) as f:
        assert 'Left out (not finished): y seed 1.' in f.read()
    with pytest.raises(ValueError, match='nothing to tabulate'):
        rc.compare([('z', 'z.py')], [0], budget, 'none', [0.02], out,
                   log=logs.append, train=False)


def test_the_record_names_the_gpu_the_runs_trained_on(tmp_path,
                                                      monkeypatch):
    """MMEngine's Runner trains on a GPU when it sees one: the record must
    say so (it said 'CPU ...' for runs trained on an H100)."""
    import torch
    fake_training(tmp_path, monkeypatch,
                  lambda name, config, seed, *a, **k: fake_run(
                      name, seed, 0.5, 0.4))

    def compare(out):
        return rc.compare([('x', 'x.py')], [0], ce.Budget(iters=1),
                          str(tmp_path / 'data'), [0.02], str(out),
                          log=lambda *a: None)

    monkeypatch.setattr(executors, 'get_device', lambda: 'cpu')
    assert compare(tmp_path / 'cpu')['machine'].startswith('CPU ')
    monkeypatch.setattr(executors, 'get_device', lambda: 'cuda')
    monkeypatch.setattr(torch.cuda, 'get_device_name',
                        lambda device=None: 'NVIDIA FakeGPU')
    line = compare(tmp_path / 'gpu')['machine']
    assert line.startswith('NVIDIA FakeGPU + CPU ')


def test_only_keeps_the_named_recipes_in_set_order():
    got = rc.resolve_recipes('parts', only=['CBNet', 'stock (GELU, OPE)'])
    assert [n for n, _ in got] == ['stock (GELU, OPE)', 'CBNet']
    with pytest.raises(ValueError, match=r"no recipe named \['nope'\]"):
        rc.resolve_recipes('arch', only=['nope'])


def test_cli_preset_fills_what_is_not_given():
    tool = load_tool('analysis_tools/compare_recipes.py')
    bench = rc.PRESETS['bench']
    args = tool.parse_args(['--set', 'parts', '--preset', 'bench'])
    assert (args.iters, args.batch_size, tuple(args.img_scale)) == (
        bench.iters, bench.batch_size, bench.img_scale)
    parts = rc.resolve_recipes('parts')
    assert tool.data_and_betas(args, parts) == (bench.data_root,
                                                [0.005, 0.01, 0.02])
    args = tool.parse_args(['--set', 'arch', '--preset', 'bench',
                            '--iters', '7', '--img-scale', '64', '32',
                            '--data-root', 'elsewhere'])
    assert args.iters == 7 and tuple(args.img_scale) == (64, 32)
    assert tool.data_and_betas(args, parts)[0] == 'elsewhere'
    args = tool.parse_args(['--set', 'arch'])
    assert args.iters == 120 and args.img_scale is None
    assert tool.data_and_betas(args, parts)[0] == 'data/cityscapes_like'
    # real-data recipes: their config's data, no betas
    realfog = rc.resolve_recipes('realfog')
    data_root, betas = tool.data_and_betas(args, realfog)
    assert betas == [] and data_root != 'data/cityscapes_like'


def test_resume_iter_reads_mmengines_marker(tmp_path):
    assert rc.resume_iter(str(tmp_path)) is None
    marker = tmp_path / 'last_checkpoint'
    marker.write_text(str(tmp_path / 'iter_200.pth'))
    assert rc.resume_iter(str(tmp_path)) is None  # the file is gone
    (tmp_path / 'iter_200.pth').write_bytes(b'')
    assert rc.resume_iter(str(tmp_path)) == 200
    marker.write_text(str(tmp_path / 'epoch_3.pth'))
    (tmp_path / 'epoch_3.pth').write_bytes(b'')
    assert rc.resume_iter(str(tmp_path)) is None
    assert [ce.checkpoint_interval(n) for n in (1, 6, 120, 600, 601)] == \
        [1, 1, 20, 100, 101]


def test_a_killed_run_resumes_from_its_last_checkpoint(
        cityscapes_like_root, tmp_path):
    """A run stopped at iteration 3 of 6 (a session's end) goes on from
    its checkpoint of iteration 3 when the comparison is run again, and
    its record says so."""
    crpn = osp.join(ROOT, 'configs', 'demo', 'rpn',
                    'crpn_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
    budget = ce.Budget(iters=6, batch_size=2, warmup_iters=2, num_workers=0)
    args = ('CRPN', crpn, 0, budget, cityscapes_like_root, [],
            str(tmp_path))
    run_dir = osp.dirname(rc.result_file(str(tmp_path), 'CRPN', 0))
    cfg = ce.budget_cfg(crpn, budget, 0, cityscapes_like_root, run_dir)
    assert cfg.resume is False
    assert cfg.default_hooks.checkpoint.interval == 1
    # "killed" after 3 iterations: the test of iteration 6's weights fails
    with pytest.raises(Exception):
        rc.run_recipe(*args, cfg_options={'train_cfg.max_iters': 3})
    assert rc.resume_iter(run_dir) == 3
    cfg = ce.budget_cfg(crpn, budget, 0, cityscapes_like_root, run_dir)
    assert cfg.resume is True
    # MMEngine resumes from load_from: the file found in the work dir
    assert cfg.load_from == osp.join(run_dir, 'iter_3.pth')
    result = rc.run_recipe(*args)
    assert result['resumed_at_iter'] == 3
    assert result['train_time_extrapolated'] is True
    assert result['train_time_s'] > 0
    assert osp.isfile(rc.checkpoint_file(str(tmp_path), 'CRPN', 0, budget))
    logs = glob.glob(osp.join(run_dir, '*', '*.log'))
    assert any('Resuming' in open(p).read() or 'resumed' in open(p).read()
               for p in logs), logs
