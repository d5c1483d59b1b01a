"""Pretrained loading of CBNetMiT from official and mmseg layouts."""
import re
from collections import OrderedDict

import pytest
import torch
from mmdet.registry import MODELS

import cbnet_mmdet  # noqa: F401
from cbnet_mmdet.models.backbones import convert_mit_checkpoint
from cbnet_mmdet.models.backbones.mit_checkpoint import detect_mit_layout
from cbnet_mmdet.utils.checkpoint.fit import CheckpointMismatchError

TINY = dict(
    embed_dims=[8, 16, 24, 32],
    depths=[1, 2, 1, 1],
    num_heads=[1, 2, 3, 4],
    sr_ratios=[8, 4, 2, 1])


def to_official(state_dict):
    """Write an mmseg-layout MiT state dict in SegFormer's own layout.

    Written independently of the package's converter (the inverse map).
    """
    out = OrderedDict()
    for key, v in state_dict.items():
        m = re.match(r'layers\.(\d+)\.(\d+)\.(.*)', key)
        stage, part, rest = int(m[1]) + 1, int(m[2]), m[3]
        if part == 0:
            rest = rest.replace('projection.', 'proj.')
            out[f'patch_embed{stage}.{rest}'] = v
            continue
        if part == 2:
            out[f'norm{stage}.{rest}'] = v
            continue
        block, rest = rest.split('.', 1)
        pre = f'block{stage}.{block}.'
        if 'cspe' in rest:
            continue  # not part of SegFormer
        if rest.startswith('attn.attn.in_proj_'):
            kind = rest.rsplit('_', 1)[1]
            dims = v.shape[0] // 3
            out[pre + f'attn.q.{kind}'] = v[:dims].clone()
            out[pre + f'attn.kv.{kind}'] = v[dims:].clone()
        elif rest.startswith('attn.attn.out_proj.'):
            out[pre + rest.replace('attn.attn.out_proj.', 'attn.proj.')] = v
        elif rest.startswith('ffn.layers.'):
            idx, kind = rest[len('ffn.layers.'):].split('.')
            name = {'0': 'fc1', '1': 'dwconv.dwconv', '4': 'fc2'}[idx]
            if name != 'dwconv.dwconv' and kind == 'weight':
                v = v.flatten(1)  # 1x1 conv -> linear
            out[pre + f'mlp.{name}.{kind}'] = v
        else:  # norm1, norm2, attn.sr, attn.norm
            out[pre + rest] = v
    out['head.weight'] = torch.randn(10, 32)
    out['head.bias'] = torch.randn(10)
    return out


@pytest.fixture
def log_records(log_messages):
    return log_messages()


def build_from(path, **kwargs):
    model = MODELS.build(
        dict(
            type='CBNetMiT',
            arch=TINY,
            init_cfg=dict(type='Pretrained', checkpoint=str(path)),
            **kwargs))
    model.init_weights()
    return model


@pytest.fixture
def source():
    torch.manual_seed(0)
    model = MODELS.build(
        dict(type='CBNetMiT', arch=TINY, pos_encoding='ope', init_cfg=None))
    model.init_weights()
    for p in model.parameters():
        p.data.add_(torch.randn_like(p))  # every tensor distinct
    return model


def test_official_and_mmseg_layouts_load_identically(source, tmp_path,
                                                     log_records):
    src = source.state_dict()
    official = to_official(src)
    assert detect_mit_layout(official) == 'official'
    assert detect_mit_layout(src) == 'mmseg'
    torch.save(official, tmp_path / 'official.pth')
    # mmseg writes a full segmentor checkpoint: backbone.* plus a head
    seg = {f'backbone.{k}': v for k, v in src.items()}
    seg['decode_head.conv_seg.weight'] = torch.randn(19, 8, 1, 1)
    torch.save(dict(state_dict=seg, meta={}), tmp_path / 'mmseg.pth')

    from_official = build_from(tmp_path / 'official.pth')
    official_log = '\n'.join(log_records)
    log_records.clear()
    from_mmseg = build_from(tmp_path / 'mmseg.pth')
    mmseg_log = '\n'.join(log_records)

    a, b = from_official.state_dict(), from_mmseg.state_dict()
    assert a.keys() == b.keys()
    for key in a:
        if key.endswith('cspe.table'):
            assert a[key].abs().sum() == 0 and b[key].abs().sum() == 0
        else:
            assert torch.equal(a[key], src[key]), key
            assert torch.equal(b[key], src[key]), key
    # nothing dropped silently: new CSPE tables missing, heads ignored
    for text in (official_log, mmseg_log):
        assert 'missing keys' in text
        assert 'layers.0.1.0.attn.cspe.table' in text
        assert 'layers.3.1.0.attn.cspe.table' in text
    assert 'official-layout' in official_log
    assert 'head.weight, head.bias' in official_log
    assert 'decode_head.conv_seg.weight' in mmseg_log


def test_unexpected_keys_logged_mismatched_refused(source, tmp_path,
                                                   log_records):
    sd = source.state_dict()
    sd['layers.0.1.0.attn.extra'] = torch.zeros(1)
    torch.save(dict(model=sd), tmp_path / 'ckpt.pth')
    model = build_from(tmp_path / 'ckpt.pth', pos_encoding='ope')
    text = '\n'.join(log_records)
    assert 'unexpected key' in text and 'layers.0.1.0.attn.extra' in text
    assert torch.equal(model.layers[0][0].projection.weight,
                       sd['layers.0.0.projection.weight'])
    # a tensor of another shape (another MiT size) is not skipped
    sd['layers.3.2.weight'] = torch.zeros(5)
    torch.save(dict(model=sd), tmp_path / 'bad.pth')
    with pytest.raises(CheckpointMismatchError,
                       match=r'(?s)other shape \(1\): layers.3.2.weight: '
                       r'checkpoint \(5,\) vs model \(32,\)'):
        build_from(tmp_path / 'bad.pth', pos_encoding='ope')


def test_convert_strips_module_prefix_and_rejects_non_mit():
    sd = {'module.layers.0.2.weight': torch.ones(2)}
    out, ignored, layout = convert_mit_checkpoint(sd)
    assert list(out) == ['layers.0.2.weight'] and ignored == []
    assert layout == 'mmseg'
    with pytest.raises(ValueError, match='not a MiT checkpoint'):
        convert_mit_checkpoint({'conv1.weight': torch.ones(1)})
    with pytest.raises(ValueError, match='not a MiT checkpoint'):
        convert_mit_checkpoint({})
    with pytest.raises(TypeError, match='checkpoint dict'):
        convert_mit_checkpoint([1, 2])


def test_pretrained_without_checkpoint_and_missing_file(tmp_path):
    model = MODELS.build(
        dict(type='CBNetMiT', arch=TINY, init_cfg=dict(type='Pretrained')))
    with pytest.raises(KeyError, match='checkpoint'):
        model.init_weights()
    with pytest.raises(FileNotFoundError):
        build_from(tmp_path / 'nope.pth')


def test_converter_cli_writes_loadable_checkpoint(source, tmp_path, capsys):
    import importlib.util
    import os.path as osp
    root = osp.dirname(osp.dirname(osp.dirname(osp.dirname(__file__))))
    spec = importlib.util.spec_from_file_location(
        'mit2cbnet', osp.join(root, 'tools/model_converters/mit2cbnet.py'))
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    torch.save(to_official(source.state_dict()), tmp_path / 'official.pth')
    tool.main([str(tmp_path / 'official.pth'), str(tmp_path / 'conv.pth')])
    assert 'head.weight, head.bias' in capsys.readouterr().out
    model = build_from(tmp_path / 'conv.pth', pos_encoding='ope')
    for key, value in source.state_dict().items():
        assert torch.equal(model.state_dict()[key], value), key
