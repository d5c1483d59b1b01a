"""The COCO-start sets end to end on tiny fake data: realfog_coco_trunk
(a VOC folder, boxes), coco_street_coco_trunk (the COCO street
converter's output, masks) and fog_transfer_coco (trained on the clear
street set, tested on it and on the VOC folder), each from seeded
stand-ins of the converted YOLOX-Nano files built here (no weights file,
no network): the trained models started from the stand-in's trunk and
kept its batch-norm statistics."""
from dataclasses import replace

import pytest
import torch
from set_helpers import fake_coco, save_untrained_dehazer
from tool_helpers import FAST, TEST_IN_PROCESS, load_tool

from cbnet_lab import recipe_comparison as rc
from cbnet_tools import pretrained as pt
from cbnet_tools.synthetic.voc_folder import tiny_fog_folder
from cbnet_tools.synthetic.yolox_checkpoints import PROBE_NORM
from cbnet_tools.synthetic.yolox_checkpoints import tiny_yolox_nano

BUDGET = rc.Budget(iters=2, batch_size=2, warmup_iters=1, num_workers=0,
                   img_scale=(160, 96))
STEM = 'backbone.stem.conv.conv.weight'


@pytest.fixture
def fake_coco_yolox(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'weights'))
    return tiny_yolox_nano()[2]


def started_from(state, coco):
    # the batch norms kept the stand-in's statistics (norm_eval)
    torch.testing.assert_close(state[PROBE_NORM], coco[PROBE_NORM])
    # two steps at a tiny lr move the stem's weights a little, not away
    assert torch.allclose(state[STEM], coco[STEM], atol=1e-2)


def test_realfog_coco_trunk_set_end_to_end(fake_coco_yolox, tmp_path):
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=6)
    runs = str(tmp_path / 'runs')
    rows = ['Cascade R-CNN, COCO trunk', 'CBNet-PT, COCO trunk',
            'Cascade R-CNN, COCO trunk + PAFPN',
            'Cascade R-CNN, COCO trunk, stem trained']
    record = load_tool('analysis_tools/compare_recipes.py').main(
        ['--set', 'realfog_coco_trunk', '--data-root', fog, '--img-scale',
         '160', '96', '--work-dir', runs, '--only'] + rows + FAST +
        ['--cfg-options'] + TEST_IN_PROCESS)
    assert [r['recipe'] for r in record['runs']] == rows
    assert record['summary']['columns'] == [
        'box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
    for run in record['runs']:
        assert 0.0 <= run['metrics']['real fog']['coco/bbox_mAP'] <= 1.0
        state = torch.load(rc.checkpoint_file(runs, run['recipe'], 0,
                                              BUDGET),
                           map_location='cpu')['state_dict']
        started_from(state, fake_coco_yolox)
        # the stem stays as COCO left it unless the row trains it
        frozen = torch.equal(state[STEM], fake_coco_yolox[STEM])
        assert frozen != run['recipe'].endswith('stem trained')
        if 'PAFPN' in run['recipe']:
            assert 'neck.0.out_convs.0.conv.weight' in state


def test_coco_street_coco_trunk_set_end_to_end(
        cityscapes_like_root, fake_coco_yolox, tmp_path):
    fake_coco(cityscapes_like_root, str(tmp_path / 'coco'))
    load_tool('dataset_converters/coco_street.py').main(
        [str(tmp_path / 'coco'), str(tmp_path / 'street')])
    runs = str(tmp_path / 'runs')
    row = 'CBNet-PT, COCO trunk'
    record = load_tool('analysis_tools/compare_recipes.py').main(
        ['--set', 'coco_street_coco_trunk', '--data-root',
         str(tmp_path / 'street'), '--img-scale', '160', '96', '--work-dir',
         runs, '--only', row] + FAST + ['--cfg-options'] + TEST_IN_PROCESS)
    assert [r['recipe'] for r in record['runs']] == [row]
    assert record['summary']['columns'] == [
        'box AP', 'box AP50', 'mask AP', 'mask AP50', 'mIoU']
    metrics = record['runs'][0]['metrics']['coco street']
    assert 'coco/segm_mAP' in metrics and 'cityscapes/mIoU' in metrics
    state = torch.load(rc.checkpoint_file(runs, row, 0, BUDGET),
                       map_location='cpu')['state_dict']
    started_from(state, fake_coco_yolox)


def test_coco_street_coco_trunk_parts_set_end_to_end(
        cityscapes_like_root, fake_coco_yolox, tmp_path):
    """The parts set's one-head row trains the paper's single mask head;
    its whole CBNet-PT row is the coco_street_coco_trunk set's run, read
    back by that set from the shared work dir without training again."""
    fake_coco(cityscapes_like_root, str(tmp_path / 'coco'))
    street = str(tmp_path / 'street')
    load_tool('dataset_converters/coco_street.py').main(
        [str(tmp_path / 'coco'), street])
    runs = str(tmp_path / 'runs')
    one_head, whole = ('Cascade Mask R-CNN +last-stage mask, COCO trunk',
                       'CBNet-PT, COCO trunk')
    common = ['--data-root', street, '--img-scale', '160', '96',
              '--work-dir', runs]
    compare = load_tool('analysis_tools/compare_recipes.py').main
    record = compare(['--set', 'coco_street_coco_trunk_parts', '--only',
                      one_head, whole] + common + FAST + ['--cfg-options'] +
                     TEST_IN_PROCESS)
    by_name = {r['recipe']: r for r in record['runs']}
    assert list(by_name) == [one_head, whole]
    state = torch.load(rc.checkpoint_file(runs, one_head, 0, BUDGET),
                       map_location='cpu')['state_dict']
    started_from(state, fake_coco_yolox)
    heads = {k.split('.')[2] for k in state
             if k.startswith('roi_head.mask_head.')}
    assert not heads & {'0', '1', '2'}, heads  # one head, not one per stage
    state = torch.load(rc.checkpoint_file(runs, whole, 0, BUDGET),
                       map_location='cpu')['state_dict']
    assert {'0', '1', '2'} <= {k.split('.')[2] for k in state
                               if k.startswith('roi_head.mask_head.')}
    again = compare(['--set', 'coco_street_coco_trunk', '--only', whole,
                     '--report-only'] + common + FAST + ['--cfg-options'] +
                    TEST_IN_PROCESS)
    assert [r['metrics'] for r in again['runs']] == \
        [by_name[whole]['metrics']]


def test_fog_transfer_coco_set_end_to_end(street_and_fog, fake_coco_yolox,
                                          tmp_path, monkeypatch):
    """Trained on the clear street photos, tested there and on real fog:
    the COCO-trunk cascade (clear, CBNet-DD), YOLOX-Nano whole at its own
    batch, and dehazers in front of each clear row's checkpoint (trains
    nothing)."""
    street, fog = street_and_fog
    monkeypatch.chdir(tmp_path)  # the dehazer checkpoint path is relative
    save_untrained_dehazer(tmp_path)
    cascade, yolox = ('Cascade Mask R-CNN, COCO trunk, clear',
                      'YOLOX-Nano COCO, clear')
    rows = [cascade, 'Cascade Mask R-CNN, COCO trunk, CBNet-DD',
            'dehazer + Cascade Mask R-CNN, COCO trunk, clear (test only)',
            yolox, 'DCP + YOLOX-Nano COCO, clear (test only)']
    runs = str(tmp_path / 'runs')
    record = load_tool('analysis_tools/compare_recipes.py').main(
        ['--set', 'fog_transfer_coco', '--data-root', street,
         '--transfer-root', fog, '--img-scale', '160', '96', '--work-dir',
         runs, '--only'] + rows + FAST + ['--cfg-options'] +
        TEST_IN_PROCESS)
    by_name = {r['recipe']: r for r in record['runs']}
    assert list(by_name) == rows
    assert record['summary']['conditions'] == ['coco street', 'real fog']
    for name, run in by_name.items():
        assert list(run['metrics']) == ['coco street', 'real fog']
        assert 0.0 <= run['metrics']['real fog']['coco/bbox_mAP'] <= 1.0
        assert 'coco/segm_mAP' not in run['metrics']['real fog']
        # YOLOX predicts boxes only; the cascades masks too
        assert ('coco/segm_mAP' in run['metrics']['coco street']) == \
            ('YOLOX' not in name)
        if '(test only)' in name:
            assert run['train_time_s'] is None
            assert run['weights_of'] == (yolox if 'YOLOX' in name
                                         else cascade)
    # YOLOX-Nano trained at its own batch of 4 for half the iterations
    # (the same images seen), from the stand-in's 8-class file
    yolox_budget = replace(BUDGET, batch_size=4, iters=1)
    state = torch.load(rc.checkpoint_file(runs, yolox, 0, yolox_budget),
                       map_location='cpu')['state_dict']
    assert state['bbox_head.multi_level_conv_cls.0.weight'].shape[0] == 8
    torch.testing.assert_close(state[PROBE_NORM], fake_coco_yolox[PROBE_NORM])
    state = torch.load(rc.checkpoint_file(runs, cascade, 0, BUDGET),
                       map_location='cpu')['state_dict']
    started_from(state, fake_coco_yolox)
