"""The pretrained-trunk sets end to end on tiny fake data:
``coco_street`` (real masks: COCO json -> tools/dataset_converters/
coco_street.py -> its recipes, mask AP / box AP / mIoU) and
``realfog_pretrained`` (a VOC folder, box AP / AP50 / AP_s/m/l), each
with a fake MobileNetV2 weights file (``fake_weights``, conftest.py; no
wheel, no network)."""
import json
import os.path as osp

import pytest
import torch
from set_helpers import fake_coco
from tool_helpers import FAST, TEST_IN_PROCESS, load_tool

from cbnet_lab import recipe_comparison as rc
from cbnet_tools.synthetic.voc_folder import tiny_fog_folder
from cbnet_mmdet.datasets.voc_fog import CITYSCAPES_CLASSES
from cbnet_tools import pretrained as pt


def test_coco_street_converter_and_set_end_to_end(
        cityscapes_like_root, fake_weights, tmp_path, capsys):
    images, anns = fake_coco(cityscapes_like_root, str(tmp_path / 'coco'))
    converter = load_tool('dataset_converters/coco_street.py')
    stats = converter.main([str(tmp_path / 'coco'),
                            str(tmp_path / 'street')])
    # every photo in one split; rider (COCO has none) dropped
    assert sum(stats['images'].values()) == len(images)
    riders = sum(a['category_id'] == 41 for a in anns)
    assert stats['dropped'] == riders > 0
    out = {}
    for split in ('train', 'val'):
        with open(tmp_path / 'street' / 'annotations' /
                  f'instances_{split}.json') as f:
            out[split] = json.load(f)
        assert [c['name'] for c in out[split]['categories']] == \
            list(CITYSCAPES_CLASSES)
    ids = [{i['id'] for i in out[s]['images']} for s in ('train', 'val')]
    assert not ids[0] & ids[1] and out['val']['images']
    # the same split again (seeded), and another seed gives another
    assert converter.convert(json.load(open(
        tmp_path / 'coco' / 'annotations' / 'instances.json')))['val'] == \
        out['val']

    tool = load_tool('analysis_tools/compare_recipes.py')
    argv = ['--set', 'coco_street', '--data-root',
            str(tmp_path / 'street'), '--img-scale', '256', '128',
            '--work-dir', str(tmp_path / 'runs')] + FAST + \
        ['--cfg-options'] + TEST_IN_PROCESS
    args = tool.parse_args(argv)
    assert args.preset == 'coco_street'  # the set's own preset
    record = tool.main(argv)
    assert [r['recipe'] for r in record['runs']] == \
        [n for n, _ in rc.RECIPE_SETS['coco_street']]
    assert record['summary']['conditions'] == ['coco street']
    assert record['summary']['columns'] == [
        'box AP', 'box AP50', 'mask AP', 'mask AP50', 'mIoU']
    for run in record['runs']:
        metrics = run['metrics']['coco street']
        assert 'coco/segm_mAP' in metrics and 'cityscapes/mIoU' in metrics
    md = (tmp_path / 'runs' / 'compare.md').read_text()
    assert '**coco street**' in md and 'foggy' not in md


def test_realfog_pretrained_set_end_to_end(fake_weights, tmp_path, capsys):
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=10)
    tool = load_tool('analysis_tools/compare_recipes.py')
    names = [n for n, _ in rc.RECIPE_SETS['realfog_pretrained']]
    argv = ['--set', 'realfog_pretrained', '--data-root', fog,
            '--img-scale', '160', '96', '--work-dir',
            str(tmp_path / 'runs')] + FAST
    options = ['--cfg-options'] + TEST_IN_PROCESS
    # the YOLOX row left for later (a sweep stopped before it)
    record = tool.main(argv + ['--only'] + names[:-1] + options)
    assert [r['recipe'] for r in record['runs']] == names[:-1]
    assert record['summary']['columns'] == [
        'box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
    for run in record['runs']:
        metrics = run['metrics']['real fog']
        assert 0.0 <= metrics['coco/bbox_mAP'] <= 1.0
        assert 'coco/segm_mAP' not in metrics
    # the trained models started from the fake trunk (frozen stem kept)
    ckpt = torch.load(rc.checkpoint_file(
        str(tmp_path / 'runs'), names[0], 0,
        rc.Budget(iters=2, batch_size=2, warmup_iters=1, num_workers=0,
                  img_scale=(160, 96))), map_location='cpu')
    torch.testing.assert_close(ckpt['state_dict']['backbone.conv1.conv.'
                                                  'weight'],
                               fake_weights['conv1.conv.weight'])
    # the whole set: only that run is trained, every run tabulated
    capsys.readouterr()
    record = tool.main(argv + options)
    assert [r['recipe'] for r in record['runs']] == names
    said = capsys.readouterr().out
    assert said.count('already done') == len(names) - 1
    assert said.count(': training') == 1


def test_missing_weights_stop_before_any_training(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'none'))
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=4)
    tool = load_tool('analysis_tools/compare_recipes.py')
    with pytest.raises(FileNotFoundError,
                       match='fetch_pretrained.py mobilenet_v2'):
        tool.main(['--set', 'realfog_pretrained', '--data-root', fog,
                   '--work-dir', str(tmp_path / 'runs')] + FAST)
    assert not osp.exists(tmp_path / 'runs' / 'Cascade_R-CNN')


def test_realfog_pretrained_parts_set_end_to_end(fake_weights, tmp_path):
    """The swapped-part rows train and score on a VOC folder, each from
    the fake trunk (the two whole recipes, at the full trunk lr, are the
    realfog_pretrained_finetune rows: the previous test's recipes with
    one lr_mult changed, tests/test_configs/test_pretrained_finetune_
    configs.py)."""
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=6)
    tool = load_tool('analysis_tools/compare_recipes.py')
    whole = dict(rc.RECIPE_SETS['realfog_pretrained_finetune'])
    swapped = [n for n, _ in rc.RECIPE_SETS['realfog_pretrained_parts']
               if n not in whole]
    assert len(swapped) == 6
    runs = str(tmp_path / 'runs')
    record = tool.main(
        ['--set', 'realfog_pretrained_parts', '--data-root', fog,
         '--img-scale', '160', '96', '--work-dir', runs, '--only'] +
        swapped + FAST + ['--cfg-options'] + TEST_IN_PROCESS)
    assert [r['recipe'] for r in record['runs']] == swapped
    assert record['summary']['columns'] == [
        'box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
    budget = rc.Budget(iters=2, batch_size=2, warmup_iters=1,
                       num_workers=0, img_scale=(160, 96))
    for run in record['runs']:
        assert 0.0 <= run['metrics']['real fog']['coco/bbox_mAP'] <= 1.0
        ckpt = torch.load(rc.checkpoint_file(runs, run['recipe'], 0, budget),
                          map_location='cpu')
        torch.testing.assert_close(
            ckpt['state_dict']['backbone.conv1.conv.weight'],
            fake_weights['conv1.conv.weight'])
