"""Real fog: box evaluation of a checkpoint on a VOC folder (AP-drop tool,
the condition of the folder a config is written for), the harness's
real-data conditions, and the ``realfog`` set end to end on a tiny
generated VOC folder."""
import glob
import json
import os.path as osp

import numpy as np
import pytest
import torch
from mmengine.config import Config
from set_helpers import save_untrained_dehazer
from tool_helpers import load_tool

from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
from cbnet_tools.synthetic.voc_folder import (tiny_fog_folder,
                                              write_voc_folder)
from cbnet_lab import config_edits as ce
from cbnet_lab import recipe_comparison as rc
from cbnet_lab import report
from cbnet_lab.ap_drop import ap_drop, with_empty_coco_results
from cbnet_lab.sets import data_condition

ROOT = osp.dirname(osp.dirname(osp.dirname(osp.abspath(__file__))))
REALFOG = osp.join(ROOT, 'configs', 'realfog')
RECIPES = dict(rc.RECIPE_SETS['realfog'])
RECIPES = {n: osp.join(ROOT, 'configs', p) for n, p in RECIPES.items()}
DATASET_CFG = osp.join(ROOT, 'configs', '_base_', 'datasets',
                       'cityscapes_instance.py')


def oracle_cfg(cfg, root, tmp_path, drop_class=None):
    """``cfg``'s test set (no resize: the oracle's boxes are in the
    original image) around the oracle, on ``root``, and a checkpoint."""
    ce.replace_data_root(cfg, root)
    cfg.default_scope = 'mmdet'
    # the evaluation tests' oracle (conftest.py): predicts the ground truth
    cfg.model = dict(type='_CBNetTestOracle', drop_class=drop_class,
                     data_preprocessor=dict(type='DetDataPreprocessor'))
    cfg.test_cfg = dict(type='TestLoop')
    ds = cfg.test_dataloader.dataset
    ds.pipeline = [p for p in ds.pipeline if p['type'] != 'Resize']
    cfg.test_dataloader.update(num_workers=0, persistent_workers=False)
    cfg.log_level = 'WARNING'
    ckpt = str(tmp_path / 'oracle.pth')
    torch.save({'state_dict': {'dummy': torch.zeros(1)}}, ckpt)
    return cfg, ckpt


@pytest.fixture(scope='module')
def fog_root(tmp_path_factory):
    root = str(tmp_path_factory.mktemp('voc_fog') / 'fog')
    tiny_fog_folder(root, num_images=10)
    return root


def val_classes(fog_root):
    """Labels present in the val split, read from the dataset."""
    from mmdet.registry import DATASETS
    from mmengine.registry import init_default_scope
    init_default_scope('mmdet')
    ds = DATASETS.build(dict(type='CBNetVOCFogDataset', data_root=fog_root,
                             ann_file='', split='val', test_mode=True,
                             pipeline=[]))
    return {i['bbox_label'] for k in range(len(ds))
            for i in ds.get_data_info(k)['instances']}


def test_real_fog_config_scores_an_oracle_100(fog_root, tmp_path):
    """The realfog CBNet config's val split, scored by CocoMetric from the
    dataset's own ground truth: every box predicted -> AP 100."""
    cfg = Config.fromfile(osp.join(
        REALFOG, 'cbnet_mit-b0_nasfpn-box_1xb4-demo_voc-fog.py'))
    # written for DAWN's folder: real fog, whatever folder it tests
    real = data_condition(cfg.data_root)
    assert real == 'real fog' and ce.default_betas(real) == []
    assert ce.default_betas(data_condition(Config.fromfile(
        DATASET_CFG).data_root)) == [0.02]
    cfg, ckpt = oracle_cfg(cfg, fog_root, tmp_path)
    table = ap_drop(ce.ap_drop_cfgs(cfg, ckpt, str(tmp_path / 'all'), [],
                                    condition=real))
    assert list(table['metrics']) == ['real fog']
    assert table['rows'][0]['box AP'] == pytest.approx(100.0)
    assert table['rows'][0]['mask AP'] is None  # boxes only
    with pytest.raises(ValueError, match='no synthetic-fog twin'):
        ce.ap_drop_cfgs(cfg, ckpt, str(tmp_path / 'x'), [0.02],
                        condition=real)


def test_ap_drop_tool_tests_any_config_on_real_fog(fog_root, tmp_path):
    """ap_drop.py --real-fog on a Cityscapes instance config (masks in its
    pipeline and evaluators): every person left out -> that class's AP is
    0 and the mAP is 100 x (classes with ground truth - 1) / classes."""
    present = val_classes(fog_root)
    person = CITYSCAPES_CLASSES.index('person')
    assert person in present and len(present) >= 2
    cfg, ckpt = oracle_cfg(Config.fromfile(DATASET_CFG), fog_root, tmp_path,
                           drop_class=person)
    cfg_file = str(tmp_path / 'oracle_cfg.py')
    cfg.dump(cfg_file)
    tool = load_tool('analysis_tools/ap_drop.py')
    table = tool.main([cfg_file, ckpt, '--real-fog', fog_root, '--out-dir',
                       str(tmp_path / 'out')])
    assert [r['condition'] for r in table['rows']] == ['real fog']
    assert table['rows'][0]['box AP'] == pytest.approx(
        100.0 * (len(present) - 1) / len(present), abs=0.05)  # 3 decimals
    assert table['rows'][0]['mIoU'] is None
    # one condition, nothing to drop from: no drop column printed
    assert not any('drop' in c for c in table['columns'])
    assert 'drop' not in (tmp_path / 'out' / 'ap_drop.md').read_text()
    with open(tmp_path / 'out' / 'ap_drop.json') as f:
        assert json.load(f)['rows'] == table['rows']
    real = ce.real_fog_cfg(Config.fromfile(DATASET_CFG), '/data/rtts',
                           img_suffix='.png')
    ds = real.test_dataloader.dataset
    assert (ds.type, ds.split, ds.img_suffix) == \
        ('CBNetVOCFogDataset', 'val', '.png')
    assert [t for t in ds.pipeline if t['type'] == 'LoadAnnotations'][0][
        'with_mask'] is False
    assert 'instances' in ds.pipeline[-1]['meta_keys']


def test_a_model_that_detects_nothing_scores_0_not_missing(tmp_path):
    """MMDet's CocoMetric reports no metric when nothing is detected on
    any image; the AP of no detection is 0, and the table says so."""
    root = str(tmp_path / 'cars')
    write_voc_folder(root, {f'c{k}': [('car', (10, 10, 50, 40))]
                            for k in range(4)})
    car = CITYSCAPES_CLASSES.index('car')
    cfg, ckpt = oracle_cfg(Config.fromfile(osp.join(
        REALFOG, 'cbnet_mit-b0_nasfpn-box_1xb4-demo_voc-fog.py')),
        root, tmp_path, drop_class=car)
    table = ap_drop(ce.ap_drop_cfgs(cfg, ckpt, str(tmp_path / 'none'), [],
                                    condition=ce.REAL_FOG))
    assert table['metrics']['real fog'] == {
        'coco/bbox_mAP': 0.0, 'coco/bbox_mAP_50': 0.0,
        'coco/bbox_mAP_75': 0.0}
    assert table['rows'][0]['box AP'] == 0.0
    # only the evaluator's missing kinds; present metrics are kept
    cfg = Config(dict(test_evaluator=[
        dict(type='CocoMetric', metric=['bbox', 'segm', 'proposal'],
             prefix='x'),
        dict(type='CBNetInstanceMIoUMetric')]))
    filled = with_empty_coco_results(cfg, {'x/bbox_mAP': 0.5})
    assert filled == {'x/bbox_mAP': 0.5, 'x/segm_mAP': 0.0,
                      'x/segm_mAP_50': 0.0, 'x/segm_mAP_75': 0.0}


def fake_run(recipe, seed, ap):
    return dict(recipe=recipe, seed=seed, train_time_s=5.0,
                metrics={'real fog': {'coco/bbox_mAP': ap,
                                      'coco/bbox_mAP_50': 2 * ap}})


def test_summary_table_and_bars_on_one_real_condition(tmp_path):
    runs = [fake_run('A', s, ap) for s, ap in enumerate([0.1, 0.2, 0.15])]
    runs.append(fake_run('B', 0, 0.05))
    summary = rc.summarize(runs, [], reference='real fog')
    assert summary['conditions'] == ['real fog']
    assert summary['columns'] == ['box AP', 'box AP50']
    stat = summary['summary']['A']['real fog']['box AP']
    assert stat['mean'] == pytest.approx(15.0)
    assert stat['std'] == pytest.approx(np.std([10, 20, 15], ddof=1))
    md = report.to_markdown(summary)
    assert '**real fog**' in md and 'drop' not in md
    assert '| A | 15.0 +- 5.0 | 30.0 +- 10.0 | 5.0 +- 0.0 |' in md
    path = report.plot(summary, [], str(tmp_path / 'bars.png'))
    with open(path, 'rb') as f:
        assert f.read(8) == b'\x89PNG\r\n\x1a\n'


def test_reference_condition_and_mixing(tmp_path):
    realfog = rc.resolve_recipes('realfog')
    assert rc.reference_condition(realfog) == 'real fog'
    assert rc.reference_condition(rc.resolve_recipes('arch')) == 'clear'
    with pytest.raises(ValueError, match='tested on different data'):
        rc.reference_condition(realfog[:1] + rc.resolve_recipes('arch'))
    with pytest.raises(ValueError, match='no foggy betas apply'):
        rc.compare(realfog, [0], ce.Budget(iters=1), str(tmp_path), [0.02],
                   str(tmp_path / 'out'))
    with pytest.raises(FileNotFoundError, match='give its folder'):
        rc.compare(realfog, [0], ce.Budget(iters=1), str(tmp_path / 'no'),
                   [], str(tmp_path / 'out'))


@pytest.mark.slow
def test_realfog_set_end_to_end(fog_root, tmp_path, monkeypatch, capsys,
                                restore_environ):
    """compare_recipes.py --set realfog on the tiny VOC folder, 2
    iterations, one seed: every recipe trains, is tested on the val split
    under 'real fog' (box AP only, no foggy betas), the table, record and
    bar plot are written; a rerun reads the runs back."""
    monkeypatch.chdir(tmp_path)  # the dehazer checkpoint path is relative
    save_untrained_dehazer(tmp_path)
    tool = load_tool('analysis_tools/compare_recipes.py')
    argv = ['--set', 'realfog', '--data-root', fog_root, '--seeds', '0',
            '--iters', '2', '--batch-size', '2', '--num-workers', '0',
            '--warmup-iters', '1', '--work-dir', str(tmp_path / 'out'),
            # the tiny images at their size (no upscaling), tested in
            # process: seconds per recipe
            '--cfg-options',
            'train_dataloader.dataset.pipeline.2.scale=(160,96)',
            'test_dataloader.dataset.pipeline.2.scale=(160,96)',
            'test_dataloader.num_workers=0',
            'test_dataloader.persistent_workers=False']
    record = tool.main(argv)
    names = [n for n, _ in rc.RECIPE_SETS['realfog']]
    assert [r['recipe'] for r in record['runs']] == names
    assert record['betas'] == [] and record['set'] == 'realfog'
    summary = record['summary']
    assert summary['conditions'] == ['real fog']
    assert summary['columns'] == ['box AP', 'box AP50']
    for run in record['runs']:
        metrics = run['metrics']['real fog']
        # an untrained YOLOX predicts nothing above its score threshold:
        # MMDet's CocoMetric then reports no metric at all ('-')
        if not run['recipe'].endswith('YOLOX-Tiny'):
            assert 0.0 <= metrics['coco/bbox_mAP'] <= 1.0
        assert 'coco/segm_mAP' not in metrics
        assert osp.isfile(tmp_path / 'out' / rc.slug(run['recipe']) /
                          'seed0' / 'iter_2.pth')
    md = (tmp_path / 'out' / 'compare.md').read_text()
    assert '**real fog**' in md and 'foggy' not in md
    assert all(f'| {n} |' in md for n in names)
    assert osp.isfile(tmp_path / 'out' / 'compare.png')
    with open(tmp_path / 'out' / 'compare.json') as f:
        assert json.load(f)['summary'] == summary
    # tools/test.py on a trained checkpoint, the config's documented way
    test_tool = load_tool('test.py')
    test_tool.main([
        RECIPES['CBNet box path'],
        str(tmp_path / 'out' / 'CBNet_box_path' / 'seed0' / 'iter_2.pth'),
        '--work-dir', str(tmp_path / 'test'), '--cfg-options',
        f'test_dataloader.dataset.data_root={fog_root}',
        'test_dataloader.num_workers=0',
        'test_dataloader.persistent_workers=False'])
    logs = glob.glob(str(tmp_path / 'test' / '*' / '*.log'))
    assert logs and 'coco/bbox_mAP:' in open(logs[0]).read()
    capsys.readouterr()
    again = tool.main(argv)
    assert capsys.readouterr().out.count('already done') == len(names)
    assert again['runs'] == record['runs']
