"""Corruption benchmark and fog-density sweep.

mPC / rPC are checked against MMDetection's own
``tools/analysis_tools/robustness_eval.py`` (shipped in the mmdet wheel
under ``.mim/tools``), run on the pickle our tool writes.
"""
import importlib.util
import json
import os.path as osp
import re

import mmdet
import numpy as np
import pytest
import torch
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.fileio import dump

from cbnet_lab.config_edits import corrupted_cfg
from cbnet_lab.robustness import (CORRUPTION_GROUPS, check_corruptions,
                                  resolve_corruptions, summarize)

ROOT = osp.join(osp.dirname(__file__), '..', '..')
DEMO = osp.join(ROOT, 'configs', 'demo',
                'cbnet_mit-b0_nasfpn_1xb4-demo_cityscapes-like.py')
MMDET_EVAL = osp.join(osp.dirname(mmdet.__file__), '.mim', 'tools',
                      'analysis_tools', 'robustness_eval.py')


def _load(path, name):
    spec = importlib.util.spec_from_file_location(name, path)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_resolve_corruptions():
    assert resolve_corruptions(['weather']) == [
        'snow', 'frost', 'fog', 'brightness'
    ]
    assert resolve_corruptions(['fog', 'weather', 'fog'])[:2] == [
        'fog', 'snow'
    ]
    assert len(resolve_corruptions(['benchmark'])) == 15
    assert len(set(CORRUPTION_GROUPS['all'])) == 19
    with pytest.raises(ValueError, match='haze'):
        resolve_corruptions(['haze'])


def test_check_corruptions():
    """The weather corruptions run; a failing one is named up front."""
    check_corruptions(CORRUPTION_GROUPS['weather'])
    with pytest.raises(ValueError, match="(?s)cannot run.*haze: KeyError"):
        check_corruptions(['fog', 'haze'])


def test_corrupted_cfg():
    cfg = Config.fromfile(DEMO)
    out = corrupted_cfg(cfg, 'fog', 3)
    pipe = out.test_dataloader.dataset.pipeline
    assert pipe[0].type == 'LoadImageFromFile'
    assert dict(pipe[1]) == dict(type='Corrupt', corruption='fog',
                                 severity=3)
    assert len(cfg.test_dataloader.dataset.pipeline) == len(pipe) - 1
    assert corrupted_cfg(cfg, 'fog', 0).test_dataloader.dataset.pipeline \
        == cfg.test_dataloader.dataset.pipeline
    with pytest.raises(ValueError, match='0-5'):
        corrupted_cfg(cfg, 'fog', 6)
    cfg.test_dataloader.dataset.pipeline = [dict(type='PackDetInputs')]
    with pytest.raises(ValueError, match='no image loader'):
        corrupted_cfg(cfg, 'fog', 1)


def _random_results(corruptions, seed=0):
    rng = np.random.default_rng(seed)
    return {
        c: {
            s: {
                'coco/bbox_mAP': float(rng.uniform(0.2, 0.6)),
                'coco/segm_mAP': float(rng.uniform(0.2, 0.6))
            }
            for s in range(6)
        }
        for c in corruptions
    }


def _mmdet_numbers(out):
    """P, mPC, rPC (fractions) from robustness_eval's printout."""
    p, mpc = [float(v) for v in re.findall(r'mAP\s+=\s+([\d.]+)', out)]
    rpc = float(re.search(r'mAP\s+=>\s+([\d.]+) %', out).group(1)) / 100
    return p, mpc, rpc


@pytest.mark.parametrize('aggregate', ['benchmark', 'all'])
@pytest.mark.parametrize('key', ['bbox', 'segm'])
def test_summary_matches_mmdet(tmp_path, capsys, aggregate, key):
    """16 corruptions (the 15 of the benchmark + one hold-out), all
    severities: P, mPC, rPC equal MMDet's robustness_eval."""
    results = _random_results(CORRUPTION_GROUPS['benchmark'] +
                              ['speckle_noise'])
    path = str(tmp_path / 'r_results.pkl')
    dump(results, path)
    mmdet_eval = _load(MMDET_EVAL, 'mmdet_robustness_eval')
    capsys.readouterr()
    mmdet_eval.get_coco_style_results(
        path, task=key, metric=['mAP'], prints=['P', 'mPC', 'rPC'],
        aggregate=aggregate)
    p, mpc, rpc = _mmdet_numbers(capsys.readouterr().out)
    ours = summarize(results, f'coco/{key}_mAP', aggregate)
    assert ours['P'] == pytest.approx(p, abs=5e-4)
    assert ours['mPC'] == pytest.approx(mpc, abs=5e-4)
    assert ours['rPC'] == pytest.approx(rpc, abs=5e-4)
    # the hold-out corruption counts only with aggregate='all'
    shifted = dict(results)
    shifted['speckle_noise'] = {
        s: {f'coco/{key}_mAP': 0.0} for s in range(6)
    }
    changed = summarize(shifted, f'coco/{key}_mAP', aggregate)['mPC']
    assert (changed == ours['mPC']) == (aggregate == 'benchmark')


def test_summary_per_corruption_and_errors():
    results = {
        'fog': {0: {'k': 0.5}, 1: {'k': 0.4}, 3: {'k': 0.2}},
        'snow': {0: {'k': 0.5}, 2: {'k': 0.25}},
    }
    s = summarize(results, 'k')
    assert s['P'] == 0.5
    assert s['per_corruption']['fog']['mPC'] == pytest.approx(0.3)
    assert s['per_corruption']['fog']['rPC_severities'] == {
        1: pytest.approx(0.8), 3: pytest.approx(0.4)}
    assert s['mPC'] == pytest.approx((0.4 + 0.2 + 0.25) / 3)
    assert s['rPC'] == pytest.approx(s['mPC'] / 0.5)
    zero = summarize({'fog': {0: {'k': 0.0}, 1: {'k': 0.0}}}, 'k')
    assert zero['rPC'] is None  # 0 / 0
    with pytest.raises(ValueError, match='severity 0'):
        summarize({'fog': {1: {'k': 0.1}}}, 'k')
    with pytest.raises(ValueError, match='fog: no severity'):
        summarize({'fog': {0: {'k': 0.1}}}, 'k')
    with pytest.raises(ValueError, match='aggregate'):
        summarize(results, 'k', aggregate='some')
    with pytest.raises(ValueError, match='severity 0'):
        summarize({}, 'k')


def test_tool_end_to_end(oracle, tmp_path, capsys):
    """The tool corrupts the images after loading (fog, 2 severities),
    tests Foggy Cityscapes (beta 0.01), writes MMDet's pickle (read back
    by MMDet's robustness_eval), JSON, markdown and the plot."""
    tool = _load(osp.join(ROOT, 'tools', 'analysis_tools',
                          'test_robustness.py'), 'test_robustness_tool')
    out = tmp_path / 'out'
    report = tool.main([oracle['cfg_file'], oracle['ckpt'], '--corruptions',
                        'fog',
                        '--severities', '0', '1', '5', '--betas',
                        '0.01', '--out-dir', str(out)])
    SEEN = oracle['seen']
    # clean once, fog 1, fog 5, beta 0.01: 3 images each
    assert len(SEEN) == 12
    printed = capsys.readouterr().out
    assert '[4/4] Foggy Cityscapes beta=0.01' in printed
    paths = [p for p, _ in SEEN]
    assert paths[:9] == paths[:3] * 3
    assert all(p.endswith('_foggy_beta_0.01.png') for p in paths[9:])
    clean, fog1, fog5 = (torch.stack([i for _, i in SEEN[k:k + 3]]).float()
                         for k in (0, 3, 6))

    # imagecorruptions' fog keeps m / (m + c) of the image (c = 1.5 at
    # severity 1, 3 at 5) under a plasma haze: the stronger the fog, the
    # further from and the less correlated with the clean image
    def corr(a, b):
        return float(torch.corrcoef(torch.stack([a.flatten(),
                                                 b.flatten()]))[0, 1])

    dist1, dist5 = ((f - clean).abs().mean() for f in (fog1, fog5))
    assert 0 < dist1 < dist5
    assert 1 > corr(fog1, clean) > corr(fog5, clean)
    # the oracle is perfect under any corruption: P = mPC = 1, rPC = 1
    box = report['summaries']['box AP']
    assert box['P'] == box['mPC'] == 1.0 and box['rPC'] == 1.0
    assert set(box['per_corruption']['fog']['severities']) == {1, 5}
    assert report['betas'][0.0]['coco/bbox_mAP'] == 1.0
    mmdet_eval = _load(MMDET_EVAL, 'mmdet_robustness_eval')
    res = mmdet_eval.get_coco_style_results(
        str(out / 'robustness_results.pkl'), task='segm', metric=['mAP'],
        prints=['P'])
    assert res[0, 0, 0] == 1.0 and res[0, 5, 0] == 1.0
    with open(out / 'robustness.json') as f:
        assert json.load(f)['summaries']['mask AP']['rPC'] == 1.0
    md = (out / 'robustness.md').read_text()
    assert '| fog | 100.0 | 100.0 | 100.0 | 100.0 |' in md
    assert '| 0.01 | 100.0 | 100.0 | 100.0 |' in md
    import matplotlib.image as mpimg
    png = mpimg.imread(str(out / 'fog_density.png'))
    assert png.shape[1] > png.shape[0]  # two panels side by side


def test_clean_run_is_added_for_mpc(oracle, tmp_path, capsys):
    """Severities without 0 still give P, mPC and rPC (the clean run is
    added, and said so), instead of silently no summary."""
    tool = _load(osp.join(ROOT, 'tools', 'analysis_tools',
                          'test_robustness.py'), 'test_robustness_tool')
    report = tool.main([oracle['cfg_file'], oracle['ckpt'], '--corruptions',
                        'fog', '--severities', '1', '--out-dir',
                        str(tmp_path / 'out')])
    assert 'severity 0 (clean) added' in capsys.readouterr().out
    assert report['summaries']['box AP']['mPC'] == 1.0


def test_tool_num_images_scores_those_images_only(oracle, tmp_path):
    """--num-images 1: one image per condition, scored against its own
    ground truth (the oracle's 100 AP; against the whole val file the
    second image's objects would count as missed)."""
    tool = _load(osp.join(ROOT, 'tools', 'analysis_tools',
                          'test_robustness.py'), 'test_robustness_tool')
    report = tool.main([oracle['cfg_file'], oracle['ckpt'], '--corruptions',
                        'fog', '--severities', '0', '1', '--num-images',
                        '1', '--out-dir', str(tmp_path / 'out')])
    paths = [p for p, _ in oracle['seen']]
    assert len(paths) == 2 and paths[0] == paths[1]
    box = report['summaries']['box AP']
    assert box['P'] == box['mPC'] == 1.0
    assert len(list((tmp_path / 'out' / 'first_1_images').iterdir())) == 1


@pytest.mark.slow  # the demo model and CBNet-DD, random weights: ~1 min
@pytest.mark.parametrize('distill', [False, True])
def test_tool_runs_demo_and_cbnet_dd(cityscapes_like_root, tmp_path,
                                     distill):
    """Where MMDet's test_robustness.py fails: the demo config
    (backbone init_cfg None) and CBNet-DD (no model.backbone)."""
    from mmengine.registry import init_default_scope
    cfg = Config.fromfile(DEMO)
    cfg.test_dataloader.dataset.data_root = cityscapes_like_root + '/'
    cfg.test_dataloader.update(num_workers=0, persistent_workers=False)
    for m in cfg.test_evaluator:
        if 'ann_file' not in m:
            continue  # the official Cityscapes metric reads gtFine
        m['ann_file'] = cityscapes_like_root + '/annotations/' \
            'instancesonly_filtered_gtFine_val.json'
    if distill:
        detector = cfg.model
        cfg.model = dict(
            type='CBNetDistiller', detector=detector,
            data_preprocessor=dict(detector.data_preprocessor,
                                   type='CBNetPairedDataPreprocessor'))
    assert cfg.model.get('backbone', {}).get('init_cfg') is None
    init_default_scope('mmdet')
    torch.manual_seed(0)
    model = MODELS.build(cfg.model)
    model.init_weights()
    ckpt = str(tmp_path / 'model.pth')
    torch.save({'state_dict': model.state_dict()}, ckpt)
    cfg.log_level = 'WARNING'
    cfg_file = str(tmp_path / 'cfg.py')
    cfg.dump(cfg_file)
    tool = _load(osp.join(ROOT, 'tools', 'analysis_tools',
                          'test_robustness.py'), 'test_robustness_tool')
    out = tmp_path / 'out'
    betas = ['--betas', '0.02'] if distill else []  # fewer runs
    report = tool.main([cfg_file, ckpt, '--corruptions', 'fog',
                        '--severities', '0', '2', '--out-dir', str(out)] +
                       betas)
    box = report['summaries']['box AP']
    assert 0.0 <= box['P'] <= 1.0 and 0.0 <= box['mPC'] <= 1.0
    assert set(report['betas']) == ({0.0, 0.02} if distill else set())
    assert (out / 'fog_density.png').is_file()
    assert (out / 'robustness_results.pkl').is_file()
