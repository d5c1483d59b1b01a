"""load_dehazer_checkpoint: own weights load, wrong ones are reported."""
import logging

import pytest
import torch
from mmdet.registry import MODELS
from mmengine.logging import MMLogger

import cbnet_dehaze  # noqa: F401
from cbnet_dehaze.models.dehazers import load_dehazer_checkpoint


def dehazer(seed, **kwargs):
    torch.manual_seed(seed)
    model = MODELS.build(dict(type='CBNetAttentionDehazer', **kwargs))
    for p in model.parameters():  # random everywhere (tail is zero-init)
        torch.nn.init.normal_(p, std=0.1)
    return model


def same(a, b):
    sa, sb = a.state_dict(), b.state_dict()
    return sa.keys() == sb.keys() and all(
        torch.equal(sa[k], sb[k]) for k in sa)


@pytest.mark.parametrize('prefix', ['', 'dehazer.',
                                    'data_preprocessor.dehazer.'])
def test_loads_bare_and_nested_checkpoints(tmp_path, prefix):
    src, dst = dehazer(0), dehazer(1)
    assert not same(src, dst)
    state = {prefix + k: v for k, v in src.state_dict().items()}
    if prefix:  # an MMEngine checkpoint also holds other modules' weights
        state['discriminator.net.0.weight'] = torch.zeros(2)
    path = tmp_path / 'ckpt.pth'
    torch.save(dict(state_dict=state, meta=dict(iter=3)), path)
    report = load_dehazer_checkpoint(dst, str(path))
    assert same(src, dst)
    assert not report['missing'] and not report['mismatched']
    assert len(report['loaded']) == len(src.state_dict())


def test_wrong_architecture_is_reported(tmp_path):
    path = tmp_path / 'c8.pth'
    torch.save(dehazer(0, channels=8).state_dict(), path)
    dst = dehazer(1, channels=16)
    before = {k: v.clone() for k, v in dst.state_dict().items()}
    with pytest.raises(RuntimeError) as err:
        load_dehazer_checkpoint(dst, str(path))
    msg = str(err.value)
    assert 'c8.pth' in msg and 'mismatched' in msg
    assert 'head.0.weight: checkpoint (8, 3, 3, 3) vs model (16, 3, 3, 3)' \
        in msg
    # strict: nothing was copied
    assert all(torch.equal(before[k], v)
               for k, v in dst.state_dict().items())

    # non-strict: what fits loads (tensors whose shape does not depend on
    # the width: tail bias, relative position tables), the rest is logged
    logger = MMLogger.get_instance('test_dehazer_ckpt', log_level='INFO')
    records = []
    handler = logging.Handler()
    handler.emit = records.append
    logger.addHandler(handler)
    report = load_dehazer_checkpoint(dst, str(path), strict=False,
                                     logger=logger)
    assert report['mismatched'] and report['loaded']
    assert any('not loaded from' in r.getMessage() and 'mismatched' in
               r.getMessage() for r in records)


def test_other_model_and_missing_file(tmp_path):
    path = tmp_path / 'disc.pth'
    disc = MODELS.build(dict(type='CBNetPatchDiscriminator'))
    torch.save(disc.state_dict(), path)
    with pytest.raises(RuntimeError, match='0 of'):
        load_dehazer_checkpoint(dehazer(0), str(path), strict=False)
    with pytest.raises(FileNotFoundError, match='nowhere.pth'):
        load_dehazer_checkpoint(dehazer(0), str(tmp_path / 'nowhere.pth'))


def test_a_file_that_is_no_checkpoint_is_named(tmp_path):
    """Read through the package's checked reader: a text file or an empty
    one gives an error naming it, not torch's unpickling message."""
    text = tmp_path / 'notes.pth'
    text.write_text('not a checkpoint\n')
    with pytest.raises(ValueError, match='notes.pth'):
        load_dehazer_checkpoint(dehazer(0), str(text))
    empty = tmp_path / 'empty.pth'
    empty.write_bytes(b'')
    with pytest.raises(ValueError, match='empty.pth.*empty'):
        load_dehazer_checkpoint(dehazer(0), str(empty))
