"""The realfog_coco set end to end on a tiny VOC folder: YOLOX-Nano from
fake COCO weights built here (80 classes, and the 8-class twin whose
classifier rows are COCO's of the same names, as the converter writes
them), zero-shot through the class map, fine-tuned with the batch norms
frozen, a row with its own budget; and the zero-shot config through
tools/test.py, the documented command."""
import glob
import os.path as osp

import pytest
import torch
from tool_helpers import FAST, TEST_IN_PROCESS, load_tool

from cbnet_lab import recipe_comparison as rc
from cbnet_tools import pretrained as pt
from cbnet_tools.synthetic.voc_folder import tiny_fog_folder
from cbnet_tools.synthetic.yolox_checkpoints import PROBE_NORM as BN
from cbnet_tools.synthetic.yolox_checkpoints import tiny_yolox_nano

ZERO_SHOT = 'YOLOX-Nano COCO, zero-shot'
FINE_TUNED = 'YOLOX-Nano COCO, fine-tuned'
LONGER = 'YOLOX-Nano COCO, fine-tuned, 24 epochs'


@pytest.fixture
def fake_coco_yolox(tmp_path, monkeypatch):
    """Seeded stand-ins of both YOLOX-Nano files where the configs look
    for them; the 80-class state dict."""
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'weights'))
    coco, street, state = tiny_yolox_nano()
    assert coco == pt.pretrained_path('yolox_nano')
    # the twin's classifier rows are the COCO rows of the same names
    cls = 'bbox_head.multi_level_conv_cls.0.weight'
    rows = torch.load(street, map_location='cpu')['state_dict'][cls]
    torch.testing.assert_close(rows[0], state[cls][0])  # person
    torch.testing.assert_close(rows[1], state[cls][0])  # rider: person
    torch.testing.assert_close(rows[2], state[cls][2])  # car
    return state


def test_realfog_coco_set_end_to_end(fake_coco_yolox, tmp_path):
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=10)
    runs = str(tmp_path / 'runs')
    tool = load_tool('analysis_tools/compare_recipes.py')
    argv = ['--set', 'realfog_coco', '--data-root', fog, '--img-scale',
            '160', '96', '--work-dir', runs, '--only', ZERO_SHOT,
            FINE_TUNED, LONGER] + FAST + ['--cfg-options'] + TEST_IN_PROCESS
    assert tool.parse_args(argv).preset == 'realfog_coco'
    record = tool.main(argv)
    by_name = {r['recipe']: r for r in record['runs']}
    assert list(by_name) == [ZERO_SHOT, FINE_TUNED, LONGER]
    assert record['summary']['columns'] == [
        'box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
    for run in record['runs']:
        assert 0.0 <= run['metrics']['real fog']['coco/bbox_mAP'] <= 1.0
    # the zero-shot row trained nothing and tested the 80-class file
    zero = by_name[ZERO_SHOT]
    assert zero['train_time_s'] is None and zero['test_only']
    assert zero['weights'] == pt.pretrained_path('yolox_nano')
    assert not glob.glob(osp.join(runs, 'YOLOX_Nano_COCO_zero_shot', '*',
                                  '*.pth'))
    # its own budget: twice the set's iterations, --iters moving it too
    assert by_name[FINE_TUNED]['budget']['iters'] == 2
    assert by_name[LONGER]['budget']['iters'] == 4
    budget = rc.Budget(iters=4, batch_size=2, warmup_iters=1, num_workers=0,
                       img_scale=(160, 96))
    ckpt = torch.load(rc.checkpoint_file(runs, LONGER, 0, budget),
                      map_location='cpu')
    assert ckpt['meta']['iter'] == 4
    state = ckpt['state_dict']
    # 8 classes, started from COCO's rows of the same names; the batch
    # norms kept their statistics (CBNetNormEvalHook)
    assert state['bbox_head.multi_level_conv_cls.0.weight'].shape[0] == 8
    torch.testing.assert_close(state[BN], fake_coco_yolox[BN])
    # a rerun trains nothing
    again = tool.main(argv)
    assert [r['recipe'] for r in again['runs']] == list(by_name)


def test_zero_shot_is_a_tools_test_command(fake_coco_yolox, tmp_path,
                                           restore_environ):
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=4)
    config = osp.join(rc.configs_root(), 'yolox_coco',
                      'yolox_nano_coco-zero-shot_dawn-fog.py')
    load_tool('test.py').main([
        config, pt.pretrained_path('yolox_nano'),
        '--work-dir', str(tmp_path / 'test'), '--cfg-options',
        f'test_dataloader.dataset.data_root={fog}'] + TEST_IN_PROCESS)
    logs = glob.glob(str(tmp_path / 'test' / '*' / '*.log'))
    assert logs and 'coco/bbox_mAP:' in open(logs[0]).read()


def test_missing_weights_name_the_fetch_command(tmp_path, monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'none'))
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=4)
    tool = load_tool('analysis_tools/compare_recipes.py')
    for row in (ZERO_SHOT, FINE_TUNED):
        with pytest.raises(FileNotFoundError,
                           match='fetch_pretrained.py yolox_nano'):
            tool.main(['--set', 'realfog_coco', '--data-root', fog,
                       '--work-dir', str(tmp_path / 'runs'), '--only',
                       row] + FAST)
    assert not glob.glob(str(tmp_path / 'runs' / '*' / '*' / '*.pth'))
